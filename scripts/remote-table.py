#!/usr/bin/env python3
"""One Markdown table from scripts/bench-remote.sh's output folder.

Usage: scripts/remote-table.py out/remote/NAME

For each path kind and run (the local file, each RTT, each RTT through the rate-capped link,
the disk cache's two visits): median and p99 frame time and their ratios to in-core's of the same
run, Stage II MiB and pre / nopre, prefetch MiB, requests per frame, KiB per request, MiB fetched
and never drawn (prefetched reps evicted unused, answers dropped unread), and the first frame,
which is the time to the first complete view when nothing is substituted in it (P_R waits for
every rep of a front: the runtime's default).
"""

import csv
import sys
from pathlib import Path


def tables(summary: Path):
    """The Markdown tables of a summary.md as lists of dicts."""
    out, head = [], None
    for line in summary.read_text().splitlines():
        if not line.startswith("|"):
            head = None
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if head is None:
            head = cells
            out.append([])
        elif not set(line) <= set("|-: "):
            out[-1].append(dict(zip(head, cells)))
    return out


def num(s):
    try:
        return float(s.replace(",", ""))
    except (ValueError, AttributeError):
        return None


def frames(path: Path):
    with path.open() as f:
        return list(csv.DictReader(f))


def run_rows(kind_dir: Path, name: str, label: str, incore):
    d = kind_dir / name
    if not (d / "summary.md").exists():
        return []
    ts = tables(d / "summary.md")
    modes = ts[0]
    net = {r["run"]: r for r in ts[1]} if len(ts) > 1 else {}
    nopre = next((num(m["Stage II MiB"]) for m in modes if m["mode"] == "nopre"), None)
    rows = []
    for m in modes:
        mode = m["mode"]
        f = frames(d / f"{mode}.csv")
        med, p99 = num(m["median ms"]), num(m["p99 ms"])
        s2 = num(m["Stage II MiB"])
        n = net.get(mode, {})
        req = num(n.get("requests", ""))
        never = sum(float(x.get("wasted_bytes") or 0) for x in f) / 2**20
        never += num(n.get("MiB ahead dropped unread", "0")) or 0
        first = f[0]
        first_ms = float(first["frame_ms"])
        complete = int(first["substituted"]) == 0
        ratio = (
            f"{med / incore[0]:.2f}, {p99 / incore[1]:.2f}"
            if incore and mode != "incore"
            else ""
        )
        rows.append(
            [
                label,
                mode,
                f"{med:.2f}",
                f"{p99:.2f}",
                ratio,
                f"{s2:.2f}",
                f"{100 * s2 / nopre:.0f}%" if mode == "pre" and nopre else "",
                m["prefetch MiB"],
                f"{req / len(f):.1f}" if req is not None else "—",
                n.get("KiB per request", "—"),
                f"{never:.2f}",
                f"{first_ms:,.0f}" + ("" if complete else " (incomplete)"),
            ]
        )
    return rows


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    root = Path(sys.argv[1])
    print(
        "| path | run | mode | median ms | p99 ms | ÷ in-core (median, p99) | Stage II MiB"
        " | pre / nopre | prefetch MiB | requests per frame | KiB per request"
        " | MiB never drawn | first frame ms |"
    )
    print("|---|---|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    for kind_dir in sorted(p for p in root.iterdir() if p.is_dir()):
        if not (kind_dir / "local" / "summary.md").exists():
            continue  # not walked (yet)
        local = tables(kind_dir / "local" / "summary.md")[0]
        ic = next(m for m in local if m["mode"] == "incore")
        incore = (num(ic["median ms"]), num(ic["p99 ms"]))
        names = [("local", "local file")]
        rtts = sorted(
            (int(p.name[3:]), p.name)
            for p in kind_dir.iterdir()
            if p.name.startswith("rtt") and p.name[3:].isdigit()
        )
        for r, name in rtts:
            names.append((name, f"RTT {r} ms"))
            for capped in sorted(kind_dir.glob(f"{name}-*mbit")):
                mbit = capped.name.split("-")[1].removesuffix("mbit")
                names.append((capped.name, f"RTT {r} ms, {mbit} Mbit/s"))
        names += [("cache-first", "disk cache, 1st visit"), ("cache-second", "disk cache, 2nd visit")]
        for name, label in names:
            for row in run_rows(kind_dir, name, label, incore):
                print("| " + kind_dir.name + " | " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
