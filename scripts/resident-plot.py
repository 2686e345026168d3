#!/usr/bin/env python3
"""Resident bytes along a path, ours against a 3D Tiles viewer's, as an SVG.

Usage: resident-plot.py OURS.csv THEIRS.csv CAP_BYTES OUT.svg [TITLE]

OURS.csv is hlod-bench's per-frame CSV (`frame`, `resident_bytes`); THEIRS.csv is
viewer/web/walk.mjs's (`pose`, `cached_bytes`). Both walk the same path, a pose
per 1/30 s: the x axis is the path's time, so that a viewer that draws fewer
frames than poses is placed where its frames fell. Standard library only.
"""
import csv
import math
import sys

W, H, L, R, T, B = 900, 420, 70, 20, 40, 50


def series(path, x_col, y_col):
    with open(path, newline="") as f:
        return [(int(r[x_col]) / 30.0, int(r[y_col]) / 1048576.0) for r in csv.DictReader(f)]


def nice_step(raw):
    """The smallest of 1, 2 and 5 times a power of ten that is at least `raw`."""
    p = 10.0 ** math.floor(math.log10(raw)) if raw > 0 else 1.0
    return next(m * p for m in (1, 2, 5, 10) if m * p >= raw)


def main():
    if len(sys.argv) < 5:
        sys.exit(__doc__)
    ours = series(sys.argv[1], "frame", "resident_bytes")
    theirs = series(sys.argv[2], "pose", "cached_bytes")
    cap = int(sys.argv[3]) / 1048576.0
    title = sys.argv[5] if len(sys.argv) > 5 else "Resident bytes along the path"
    xmax = max([x for x, _ in ours + theirs] + [1.0])
    ymax = max([y for _, y in ours + theirs] + [cap]) * 1.1
    sx = lambda x: L + (W - L - R) * x / xmax
    sy = lambda y: H - B - (H - T - B) * y / ymax
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="13">',
        f'<rect width="{W}" height="{H}" fill="white"/>',
        f'<text x="{W / 2}" y="22" text-anchor="middle" font-size="16">{title}</text>',
        f'<line x1="{L}" y1="{H - B}" x2="{W - R}" y2="{H - B}" stroke="black"/>',
        f'<line x1="{L}" y1="{T}" x2="{L}" y2="{H - B}" stroke="black"/>',
        f'<text x="{W / 2}" y="{H - 12}" text-anchor="middle">path time (s)</text>',
        f'<text x="18" y="{H / 2}" text-anchor="middle" transform="rotate(-90 18 {H / 2})">MiB</text>',
    ]
    for v, vmax, horizontal in ((0.0, ymax, True), (0.0, xmax, False)):
        step = nice_step(vmax / 6)
        while v <= vmax:
            if horizontal:
                out.append(f'<text x="{L - 6}" y="{sy(v) + 4:.1f}" text-anchor="end">{v:g}</text>')
                out.append(f'<line x1="{L}" y1="{sy(v):.1f}" x2="{W - R}" y2="{sy(v):.1f}" stroke="#ddd"/>')
            else:
                out.append(f'<text x="{sx(v):.1f}" y="{H - B + 18}" text-anchor="middle">{v:g}</text>')
            v = round(v + step, 9)
    out.append(
        f'<line x1="{L}" y1="{sy(cap):.1f}" x2="{W - R}" y2="{sy(cap):.1f}" stroke="gray" stroke-dasharray="6 4"/>'
    )
    for pts, colour in ((ours, "#1f77b4"), (theirs, "#d62728")):
        if pts:
            d = " ".join(f"{sx(x):.1f},{sy(y):.1f}" for x, y in pts)
            out.append(f'<polyline points="{d}" fill="none" stroke="{colour}" stroke-width="1.5"/>')
    out.append(f'<rect x="{W - 310}" y="{T}" width="290" height="62" fill="white" stroke="#ccc"/>')
    for k, (name, colour) in enumerate(
        (("ours: P_I's resident reps", "#1f77b4"), ("3DTilesRendererJS: its tile cache", "#d62728"), ("the cap", "gray"))
    ):
        y = T + 16 + 18 * k
        out.append(f'<line x1="{W - 300}" y1="{y - 4}" x2="{W - 270}" y2="{y - 4}" stroke="{colour}" stroke-width="2"/>')
        out.append(f'<text x="{W - 262}" y="{y}">{name}</text>')
    out.append("</svg>")
    with open(sys.argv[4], "w") as f:
        f.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
