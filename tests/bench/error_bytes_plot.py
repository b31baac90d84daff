#!/usr/bin/env python3
"""Draws relMSE against asset bytes (log-log SVG) from tests/bench/partition_sweep.sh's sweep.txt: per scene
the uniform grids, the adaptive kd-tree at the same bytes, and the SH probes of equal bytes.
Usage: error_bytes_plot.py sweep.txt out.svg [title]"""
import math, os, re, sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loglog_svg  # noqa: E402

rows = {}
for line in open(sys.argv[1]):
    m = re.match(r"(\w+?)_(grid|kd)(\w+) bytes=(\d+) neural relMSE ([0-9.e-]+) \| SH probe baseline \((\d+) bytes, neural \d+ bytes\): relMSE ([0-9.e-]+)", line)
    if not m:
        continue
    scene, kind, size, nbytes, rel, shbytes, shrel = m.groups()
    rows.setdefault(scene, []).append((kind, int(nbytes), float(rel), int(shbytes), float(shrel)))

names = {"CB": "Cornell box", "GB": "glossy Cornell box", "Z": "zdm2"}
colours = {"CB": "#1f77b4", "GB": "#d62728", "Z": "#2ca02c"}
series = []
for scene, r in rows.items():
    grid = sorted((b, e) for k, b, e, _, _ in r if k == "grid")
    kd = sorted((b, e) for k, b, e, _, _ in r if k == "kd")
    sh = sorted(set((b, e) for _, _, _, b, e in r))  # the probes of every asset's bytes
    series += [(names.get(scene, scene) + ": uniform grids", colours.get(scene, "#333"), grid, ""),
               (names.get(scene, scene) + ": adaptive kd-tree", colours.get(scene, "#333"), kd, "6,4"),
               (names.get(scene, scene) + ": SH probes", colours.get(scene, "#333"), sh, "1,4")]
pts = [p for _, _, s, _ in series for p in s]
o, X, Y, L, T, pw, ph, H = loglog_svg.frame(sys.argv[3] if len(sys.argv) > 3 else "Error against bytes (256 px validation views)", pts, 250)
o.append(f'<rect x="{L}" y="{T}" width="{pw}" height="{ph}" fill="none" stroke="#333"/>')
o.append(f'<text x="{L + pw / 2}" y="{H - 12}" text-anchor="middle">asset bytes (SH probes: their coefficients)</text>')
o.append(f'<text transform="translate(16,{T + ph / 2}) rotate(-90)" text-anchor="middle">relMSE against the reference</text>')
for i, (name, colour, s, dash) in enumerate(series):
    if not s:
        continue
    p = " ".join(f"{X(b):.1f},{Y(e):.1f}" for b, e in s)
    o.append(f'<polyline fill="none" stroke="{colour}" stroke-width="2" stroke-dasharray="{dash}" points="{p}"/>')
    for b, e in s:
        o.append(f'<circle cx="{X(b):.1f}" cy="{Y(e):.1f}" r="3" fill="{colour}"/>')
    ly = T + 14 + 16 * i
    o.append(f'<line x1="{L + pw + 10}" y1="{ly - 4}" x2="{L + pw + 40}" y2="{ly - 4}" stroke="{colour}" stroke-width="2" stroke-dasharray="{dash}"/>'
             f'<text x="{L + pw + 46}" y="{ly}">{name}</text>')
o.append("</svg>")
open(sys.argv[2], "w").write("\n".join(o) + "\n")
