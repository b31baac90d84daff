"""The log-log plot frame shared by the benchmark plots (error_bytes_plot.py, error_time_plot.py): an SVG
with a white background, a title, decade grid lines and labels. Returns the SVG's lines so far (the caller
adds the series and closes it with "</svg>") and the frame: X, Y (value -> pixel), L, T (the plot's
top-left corner), pw, ph (its size)."""
import math


def frame(title, points, right, xtick=lambda e: f"1e{e}", width=760, height=480):
    x0, x1 = math.floor(math.log10(min(x for x, _ in points))), math.ceil(math.log10(max(x for x, _ in points)))
    y0, y1 = math.floor(math.log10(min(y for _, y in points))), math.ceil(math.log10(max(y for _, y in points)))
    W, H, L, R, T, B = width, height, 70, right, 36, 52
    pw, ph = W - L - R, H - T - B
    X = lambda v: L + (math.log10(v) - x0) / (x1 - x0) * pw
    Y = lambda v: T + (1 - (math.log10(v) - y0) / (y1 - y0)) * ph
    o = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" viewBox="0 0 {W} {H}" font-family="sans-serif" font-size="12">',
         '<rect width="100%" height="100%" fill="white"/>',
         f'<text x="{L + pw / 2}" y="20" text-anchor="middle" font-size="14">{title}</text>']
    for e in range(x0, x1 + 1):
        x = X(10 ** e)
        o.append(f'<line x1="{x:.1f}" y1="{T}" x2="{x:.1f}" y2="{T + ph}" stroke="#ddd"/><text x="{x:.1f}" y="{T + ph + 16}" text-anchor="middle">{xtick(e)}</text>')
    for e in range(y0, y1 + 1):
        y = Y(10 ** e)
        o.append(f'<line x1="{L}" y1="{y:.1f}" x2="{L + pw}" y2="{y:.1f}" stroke="#ddd"/><text x="{L - 6}" y="{y + 4:.1f}" text-anchor="end">1e{e}</text>')
    return o, X, Y, L, T, pw, ph, H
