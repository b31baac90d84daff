#!/usr/bin/env python3
"""The source tree's layers, checked from its #include lines (README.md, "Layout").

Each baker/ module includes only the modules below it; formats/ and runtime/ include nothing of the baker;
the third-party libraries each have their one home (Embree in baker/render/, tinygltf and Draco in
baker/scene/). Prints every include that breaks a rule and exits 1 if there is one.

    check_layers.py SOURCE_DIR
"""
import os
import re
import sys

# Who each module may include (besides itself), lowest first.
ALLOWED = {
    "baker/util": set(),
    "baker/nn": set(),
    "baker/scene": {"baker/util"},
    "baker/lights": {"baker/util", "baker/scene", "baker/nn"},
    "baker/render": {"baker/util", "baker/scene", "baker/nn", "baker/lights"},
    "baker/bake": {"baker/util", "baker/scene", "baker/nn", "baker/lights", "baker/render"},
    "baker/validate": {"baker/util", "baker/scene", "baker/nn", "baker/lights", "baker/render", "baker/bake"},
    "baker/dist": {"baker/util", "baker/bake"},
    "baker/cmd": {"baker/util", "baker/scene", "baker/nn", "baker/lights", "baker/render", "baker/bake", "baker/validate",
                  "baker/dist"},
    "formats": set(),
    "runtime": set(),
}
# Third-party headers and the one module that may include them.
HOMES = [(re.compile(r"^embree\d*/"), "baker/render"), (re.compile(r"^(tiny_gltf\.h|draco/)"), "baker/scene"),
         (re.compile(r"^mpi\.h$"), "baker/dist")]
INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^">]+)[">]', re.M)


def module_of(rel):
    parts = rel.split("/")
    return "/".join(parts[:2]) if parts[0] == "baker" else parts[0]


def main(root):
    problems = []
    files = 0
    for top in ("baker", "formats", "runtime"):
        for dirpath, _, names in os.walk(os.path.join(root, top)):
            for name in names:
                if not name.endswith((".h", ".hpp", ".cpp", ".inl", ".c")):
                    continue
                path = os.path.join(dirpath, name)
                rel = os.path.relpath(path, root)
                module = module_of(rel)
                if module not in ALLOWED:
                    problems.append(f"{rel}: module {module} is in no layer (add it to {__file__})")
                    continue
                files += 1
                with open(path, encoding="utf-8", errors="replace") as f:
                    text = f.read()
                for m in INCLUDE.finditer(text):
                    inc = m.group(1)
                    line = text.count("\n", 0, m.start()) + 1
                    if inc.startswith("baker/"):
                        target = module_of(inc)
                        if target != module and target not in ALLOWED[module]:
                            problems.append(f"{rel}:{line}: includes {inc}, but {module} is below {target}")
                    for pattern, home in HOMES:
                        if pattern.match(inc) and module != home:
                            problems.append(f"{rel}:{line}: includes {inc}, which only {home} may")
    for p in problems:
        print(p)
    print(f"{files} files, {len(problems)} includes against the layers")
    return 1 if problems or files == 0 else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..")))
