#!/usr/bin/env python3
"""Draws relMSE against bake seconds (log-log SVG) from tests/bench/training_sweep.sh's sweep.txt, per scene
Monte Carlo targets (every points x paths) and training within the integral equation (1 to 32 rounds), and
prints the markdown table: each bake, and per scene the time each method needs to reach the error of the
paper's settings (10,000 x 512), interpolated on its lower envelope (log-log, between the nearest bakes), and
that time's ratio to Monte Carlo's and to the paper bake's own; and each integral bake's error against Monte
Carlo's envelope at the same time. Lines of several seeds (training_sweep.sh's SEEDS): the median relMSE over
the seeds (one seed's failed network would carry a mean) at the mean time.
Usage: error_time_plot.py sweep.txt out.svg"""
import math, os, re, sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import loglog_svg  # noqa: E402

rows = {}
for line in open(sys.argv[1]):
    m = re.match(r"(\w+?)_(mc|int)_(\S+) seconds=([0-9.e-]+) neural relMSE ([0-9.e-]+)", line)
    if m:
        scene, kind, tag, t, e = m.groups()
        seeds = sorted(float(v) for v in re.findall(r" s\d+=([0-9.e-]+)", line))
        if seeds:  # several seeds: their median (one seed's failed network would carry a mean)
            e = seeds[len(seeds) // 2] if len(seeds) % 2 else 0.5 * (seeds[len(seeds) // 2 - 1] + seeds[len(seeds) // 2])
        rows.setdefault(scene, []).append((kind, tag, float(t), float(e)))

names = {"CB": "Cornell box", "GB": "glossy Cornell box", "Z": "zdm2 (sky)", "BB": "bright Cornell box"}
colours = {"CB": "#1f77b4", "GB": "#d62728", "Z": "#2ca02c", "BB": "#9467bd"}


def envelope(points):
    """The lower envelope: bakes no faster bake beats in error, sorted by time."""
    env, best = [], float("inf")
    for t, e in sorted(points):
        if e < best:
            env.append((t, e))
            best = e
    return env


def time_to_reach(points, target):
    env = envelope(points)
    for k, (t, e) in enumerate(env):
        if e <= target:
            if k == 0:
                return t, "<="
            (t0, e0) = env[k - 1]
            f = (math.log(target) - math.log(e0)) / (math.log(e) - math.log(e0))
            return math.exp(math.log(t0) + f * (math.log(t) - math.log(t0))), ""
    return None, ""


def error_at(points, t):
    """Monte Carlo's lower envelope at bake time t (log-log between the nearest two; None outside it)."""
    env = envelope(points)
    for (t0, e0), (t1, e1) in zip(env, env[1:]):
        if t0 <= t <= t1:
            f = (math.log(t) - math.log(t0)) / (math.log(t1) - math.log(t0))
            return math.exp(math.log(e0) + f * (math.log(e1) - math.log(e0)))
    return None


series = []
equal = ["| scene | integral rounds | seconds | integral relMSE | Monte Carlo's envelope at that time | Monte Carlo / integral |",
         "|---|---|---|---|---|---|"]
table = ["| scene | method | bake | seconds | relMSE |", "|---|---|---|---|---|"]
summary = ["| scene | paper's settings (10,000 x 512): relMSE, seconds | Monte Carlo: seconds to reach it | integral: seconds to reach it | "
           "ratio to Monte Carlo | ratio to the paper's bake |",
           "|---|---|---|---|---|---|"]
for scene, r in rows.items():
    mc = [(t, e) for k, _, t, e in r if k == "mc"]
    it = sorted(((int(tag[1:]), t, e) for k, tag, t, e in r if k == "int"))
    series += [(names.get(scene, scene) + ": Monte Carlo", colours.get(scene, "#333"), sorted(mc), "", True),
               (names.get(scene, scene) + ": integral", colours.get(scene, "#333"), [(t, e) for _, t, e in it], "6,4", False)]
    for k, tag, t, e in sorted(r, key=lambda x: (x[0] != "mc", x[2])):
        label = tag.replace("x", " points x ") + " paths" if k == "mc" else tag[1:] + " rounds"
        table.append(f"| {names.get(scene, scene)} | {'Monte Carlo' if k == 'mc' else 'integral'} | {label} | {t:.2f} | {e:.4g} |")
    for g, t, e in it:
        em = error_at(mc, t)
        equal.append(f"| {names.get(scene, scene)} | {g} | {t:.2f} | {e:.4g} | " +
                     (f"{em:.4g} | {em / e:.2f}x |" if em else "(outside its bakes) | |"))
    paper = [(t, e) for k, tag, t, e in r if k == "mc" and tag == "10000x512"]
    if paper:
        pt, pe = paper[0]
        tm, fm = time_to_reach(mc, pe)
        ti, fi = time_to_reach([(t, e) for _, t, e in it], pe)
        ratio = f"**{tm / ti:.1f}x**" if tm and ti else "not reached"
        paper_ratio = f"{pt / ti:.1f}x" if ti else "not reached"
        summary.append(f"| {names.get(scene, scene)} | {pe:.4g}, {pt:.2f} s | {fm}{tm:.2f} | "
                       f"{(fi + format(ti, '.2f')) if ti else 'not reached'} | {ratio} | {paper_ratio} |")

pts = [p for _, _, s, _, _ in series for p in s]
o, X, Y, L, T, pw, ph, H = loglog_svg.frame("Error against bake time (2 cores, 256 px validation)", pts, 230, lambda e: f"{10 ** e:g} s")
o.append(f'<text x="{L + pw / 2}" y="{H - 10}" text-anchor="middle">bake seconds (sum of the phases)</text>')
o.append(f'<text x="16" y="{T + ph / 2}" text-anchor="middle" transform="rotate(-90 16 {T + ph / 2})">relMSE against the reference</text>')
for k, (name, colour, s, dash, scatter) in enumerate(series):
    if not s:
        continue
    if scatter:  # Monte Carlo: every bake a point, the lower envelope a line
        for t, e in s:
            o.append(f'<circle cx="{X(t):.1f}" cy="{Y(e):.1f}" r="3.5" fill="none" stroke="{colour}"/>')
        s = envelope(s)
    else:
        for t, e in s:
            o.append(f'<circle cx="{X(t):.1f}" cy="{Y(e):.1f}" r="3" fill="{colour}"/>')
    d = " ".join(f"{X(t):.1f},{Y(e):.1f}" for t, e in s)
    o.append(f'<polyline points="{d}" fill="none" stroke="{colour}" stroke-width="2"' + (f' stroke-dasharray="{dash}"' if dash else "") + "/>")
    ly = T + 10 + 18 * k
    o.append(f'<line x1="{L + pw + 12}" y1="{ly}" x2="{L + pw + 40}" y2="{ly}" stroke="{colour}" stroke-width="2"' +
             (f' stroke-dasharray="{dash}"' if dash else "") + f'/><text x="{L + pw + 46}" y="{ly + 4}">{name}</text>')
o.append(f'<text x="{L + pw + 12}" y="{T + 20 + 18 * len(series)}" font-size="11">circles: Monte Carlo bakes;</text>')
o.append(f'<text x="{L + pw + 12}" y="{T + 34 + 18 * len(series)}" font-size="11">line: their lower envelope</text>')
o.append("</svg>")
open(sys.argv[2], "w").write("\n".join(o) + "\n")
print("\n".join(summary))
print()
print("\n".join(equal))
print()
print("\n".join(table))
