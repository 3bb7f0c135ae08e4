#!/usr/bin/python3
"""Charts, tables and an HTML page from `edgewise bench` results.

usage: tools/bench_report.py OUT_DIR

Reads OUT_DIR/results.csv and writes
  psnr_vs_ms.png, ssim_vs_ms.png   quality against time, one point per method
                                   per spp (mean over scenes), Pareto front per spp
  summary.md                       per method and spp: mean PSNR/SSIM/relMSE/SMAPE/ms
  scenes.md                        per scene table
  index.html                       input / outputs / reference / error maps per frame
                                   (when the bench ran with --images)
Uses Debian's python3-matplotlib.
"""
import csv
import html
import os
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def load(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    for r in rows:
        for k in ("psnr", "ssim", "relmse", "smape", "ms"):
            r[k] = float(r[k])
        r["spp"] = int(r["spp"])
        r["frame"] = int(r["frame"])
    return rows


def means(rows):
    """(method, spp) -> mean of each metric over scenes (inf PSNR capped at 100)."""
    acc = defaultdict(lambda: defaultdict(list))
    for r in rows:
        a = acc[(r["method"], r["spp"])]
        for k in ("psnr", "ssim", "relmse", "smape", "ms"):
            a[k].append(min(r[k], 100.0) if k == "psnr" else r[k])
    return {key: {k: sum(v) / len(v) for k, v in a.items()} | {"n": len(a["psnr"])} for key, a in acc.items()}


def pareto(points):
    """Points (ms, quality, label) not beaten by a faster-and-better one, by time."""
    front = []
    for p in sorted(points, key=lambda p: (p[0], -p[1])):
        if not front or p[1] > front[-1][1]:
            front.append(p)
    return front


def chart(m, metric, ylabel, path):
    methods = sorted({k[0] for k in m})
    spps = sorted({k[1] for k in m})
    markers = "osD^v<>ph*"
    cmap = plt.get_cmap("tab10")
    fig, ax = plt.subplots(figsize=(8, 5.5))
    for si, spp in enumerate(spps):
        pts = []
        for mi, meth in enumerate(methods):
            v = m.get((meth, spp))
            if not v:
                continue
            ms = max(v["ms"], 0.01)  # the noisy input costs nothing: draw it at the left edge
            ax.scatter(ms, v[metric], color=cmap(mi % 10), marker=markers[si % len(markers)], s=45, zorder=3,
                       label=meth if si == 0 else None)
            pts.append((ms, v[metric], meth))
        front = pareto(pts)
        ax.plot([p[0] for p in front], [p[1] for p in front], color="0.5", lw=1, ls="--", zorder=2)
        if front:
            ax.annotate(f"{spp} spp", (front[-1][0], front[-1][1]), textcoords="offset points", xytext=(6, 0),
                        fontsize=8, color="0.3")
    ax.set_xscale("log")
    ax.set_xlabel("time per frame (ms, log scale; fastest of repeated runs)")
    ax.set_ylabel(ylabel)
    ax.set_title(f"{ylabel} against time (mean over scenes); dashed: Pareto front per spp")
    ax.grid(True, which="both", alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    for si, spp in enumerate(spps):
        handles.append(plt.Line2D([], [], color="k", marker=markers[si % len(markers)], ls=""))
        labels.append(f"{spp} spp")
    ax.legend(handles, labels, fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_summary(m, path):
    with open(path, "w") as f:
        f.write("| method | spp | scenes | PSNR dB | SSIM | relMSE | SMAPE | ms/frame |\n")
        f.write("|---|---:|---:|---:|---:|---:|---:|---:|\n")
        for (meth, spp), v in sorted(m.items(), key=lambda kv: (kv[0][1], kv[1]["ms"])):
            f.write(f"| {meth} | {spp} | {v['n']} | {v['psnr']:.2f} | {v['ssim']:.4f} | {v['relmse']:.4g} | "
                    f"{v['smape']:.4f} | {v['ms']:.2f} |\n")


def write_scenes(rows, path):
    with open(path, "w") as f:
        f.write("| scene | spp | method | PSNR dB | SSIM | ms |\n|---|---:|---|---:|---:|---:|\n")
        for r in sorted(rows, key=lambda r: (r["scene"], r["spp"], r["ms"])):
            f.write(f"| {r['scene']} | {r['spp']} | {r['method']} | {r['psnr']:.2f} | {r['ssim']:.4f} | {r['ms']:.2f} |\n")


def write_html(rows, out):
    img = os.path.join(out, "img")
    if not os.path.isdir(img):
        return False
    frames = defaultdict(list)
    for r in rows:
        frames[(r["scene"], r["frame"], r["spp"])].append(r)
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>Edgewise benchmark</title>",
             "<style>body{font-family:sans-serif} td{text-align:center;font-size:12px} img{width:192px}</style>",
             "</head><body><h1>Edgewise benchmark</h1>",
             "<p><img src='psnr_vs_ms.png' style='width:600px'> <img src='ssim_vs_ms.png' style='width:600px'></p>"]
    for (scene, frame, spp), rs in sorted(frames.items()):
        rs.sort(key=lambda r: r["ms"])
        parts.append(f"<h2 id='{html.escape(scene)}_{frame}_{spp}'>{html.escape(scene)} frame {frame}, {spp} spp</h2>")
        parts.append("<table><tr>")
        for r in rs:
            name = f"img/{scene}_f{frame:04d}_spp{spp:04d}_{r['method']}.png"
            parts.append(f"<td><img src='{html.escape(name)}' alt='{html.escape(r['method'])}'><br>"
                         f"{html.escape(r['method'])}<br>{r['psnr']:.2f} dB, {r['ssim']:.3f}, {r['ms']:.1f} ms</td>")
        parts.append(f"<td><img src='img/{html.escape(scene)}_f{frame:04d}_ref.png' alt='reference'><br>reference</td>")
        parts.append("</tr><tr>")
        for r in rs:
            name = f"img/{scene}_f{frame:04d}_spp{spp:04d}_{r['method']}_err.png"
            parts.append(f"<td><img src='{html.escape(name)}' alt='error {html.escape(r['method'])}'><br>error x4</td>")
        parts.append("</tr></table>")
    parts.append("</body></html>")
    with open(os.path.join(out, "index.html"), "w") as f:
        f.write("\n".join(parts))
    return True


def main(argv):
    if len(argv) != 2 or argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        return 0 if len(argv) == 2 else 2
    out = argv[1]
    path = os.path.join(out, "results.csv")
    if not os.path.isfile(path):
        print(f"bench_report: no {path} (run 'edgewise bench DATA -o {out}' first)", file=sys.stderr)
        return 1
    rows = load(path)
    if not rows:
        print(f"bench_report: {path} has no rows", file=sys.stderr)
        return 1
    m = means(rows)
    chart(m, "psnr", "PSNR (dB)", os.path.join(out, "psnr_vs_ms.png"))
    chart(m, "ssim", "SSIM", os.path.join(out, "ssim_vs_ms.png"))
    write_summary(m, os.path.join(out, "summary.md"))
    write_scenes(rows, os.path.join(out, "scenes.md"))
    page = write_html(rows, out)
    print(f"bench_report: wrote charts and tables to {out}" + (" and index.html" if page else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
