#!/usr/bin/env python3
"""Draws relMSE against asset bytes (log-log SVG) from tests/bench/partition_sweep.sh's sweep.txt: per scene
the uniform grids, the adaptive kd-tree at the same bytes, and the SH probes of equal bytes.
Usage: error_bytes_plot.py sweep.txt out.svg"""
import math, re, sys

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
x0, x1 = math.floor(math.log10(min(b for b, _ in pts))), math.ceil(math.log10(max(b for b, _ in pts)))
y0, y1 = math.floor(math.log10(min(e for _, e in pts))), math.ceil(math.log10(max(e for _, e in pts)))
W, H, L, R, T, B = 760, 480, 70, 250, 36, 52
pw, ph = W - L - R, H - T - B
X = lambda v: L + (math.log10(v) - x0) / (x1 - x0) * pw
Y = lambda v: T + (1 - (math.log10(v) - y0) / (y1 - y0)) * ph
o = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" font-family="sans-serif" font-size="12">',
     '<rect width="100%" height="100%" fill="white"/>',
     f'<text x="{L + pw / 2}" y="20" text-anchor="middle" font-size="14">Error against bytes (256 px validation views)</text>']
for e in range(x0, x1 + 1):
    x = X(10 ** e)
    o.append(f'<line x1="{x:.1f}" y1="{T}" x2="{x:.1f}" y2="{T + ph}" stroke="#ddd"/><text x="{x:.1f}" y="{T + ph + 16}" text-anchor="middle">1e{e}</text>')
for e in range(y0, y1 + 1):
    y = Y(10 ** e)
    o.append(f'<line x1="{L}" y1="{y:.1f}" x2="{L + pw}" y2="{y:.1f}" stroke="#ddd"/><text x="{L - 6}" y="{y + 4:.1f}" text-anchor="end">1e{e}</text>')
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
