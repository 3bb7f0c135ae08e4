#!/usr/bin/python3
"""Charts, tables and an HTML page from `edgewise bench` results.

usage: tools/bench_report.py OUT_DIR [--oidn ANCHOR.md]

Reads OUT_DIR/results.csv and writes
  psnr_vs_ms.png, ssim_vs_ms.png   quality against time, one point per method
                                   per spp (mean over scenes), Pareto front per spp
  summary.md                       per method and spp: mean PSNR/SSIM/relMSE/SMAPE/ms
  scenes.md                        per scene table
  harm.md                          do no harm, per method: the worst and mean output
                                   minus input (dB) per spp over the scenes, and on
                                   the firefly scenes (d_firefly*) the output's mean
                                   luminance over the reference's and the peak (largest
                                   output / the reference's local maximum); also printed
  index.html                       input / outputs / reference / error maps per frame
                                   (when the bench ran with --images; every image is
                                   checked to decode in headless Chromium by
                                   tests/report, ctest -L browser)
--oidn: Intel Open Image Denoise's PSNR per scene and spp from an anchor
table (../shared/anchors/oidn-shared-test.md: | scene | 1 spp noisy | 1 spp
OIDN | ...), averaged over the scenes and spp of results.csv, drawn on the
PSNR chart as a red line per spp (it has no time measured in this run) and
added to summary.md as the gap of every method to it.
and, from OUT_DIR/temporal.csv (edgewise bench --temporal),
  temporal.md, temporal_psnr_vs_flicker.png
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
        for k in ("lum_ratio", "peak"):  # columns added later: older files lack them
            r[k] = float(r[k]) if r.get(k) not in (None, "") else float("nan")
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


def load_oidn(path, rows):
    """spp -> OIDN's mean PSNR over the scenes of rows that the anchor table has
    at that spp, and the number of those scenes; only spp where every scene
    of rows is in the table (a partial mean would not compare)."""
    table, cols = {}, []
    with open(path) as f:
        for line in f:
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if cells[0] == "scene" and not cols:
                cols = cells[1:]
            if len(cells) < 3 or not cells[0] or cells[0] in ("scene", "mean") or set(cells[0]) <= set("-: "):
                continue
            table[cells[0]] = cells[1:]
    out = {}
    for spp in sorted({r["spp"] for r in rows}):
        try:
            ci = cols.index(f"{spp} spp OIDN")
        except ValueError:
            continue
        scenes = {r["scene"] for r in rows if r["spp"] == spp}
        vals = []
        for sc in scenes:
            key = next((k for k in table if sc == k or sc.startswith(k + "_")), None)
            v = table[key][ci] if key is not None and ci < len(table[key]) else ""
            try:
                vals.append(float(v.strip("*")))
            except ValueError:
                vals = None
                break
        if vals:
            out[spp] = (sum(vals) / len(vals), len(vals))
    return out


def pareto(points):
    """Points (ms, quality, label) not beaten by a faster-and-better one, by time."""
    front = []
    for p in sorted(points, key=lambda p: (p[0], -p[1])):
        if not front or p[1] > front[-1][1]:
            front.append(p)
    return front


# Colours told apart at a glance (tab10 without its grey, then darker and
# brighter ones); past them a method gets a colour again with a hollow marker.
COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#bcbd22", "#17becf",
           "#000000", "#ffd700", "#000080", "#00ff7f", "#800000"]
SPP_MARKERS = "osD^v<>ph*"
INPUT = "input"


def chart_layout(m, metric):
    """What chart() draws: one point per method and spp ((ms, value, method,
    spp, colour, marker, hollow)) and the noisy input as a horizontal line per
    spp ((value, spp, line style)): it has no time to place on a log axis.
    Colour names the method (distinct while there are colours), the marker
    the spp."""
    methods = [x for x in sorted({k[0] for k in m}) if x != INPUT]
    spps = sorted({k[1] for k in m})
    style = {meth: (COLOURS[i % len(COLOURS)], i >= len(COLOURS)) for i, meth in enumerate(methods)}
    points, lines = [], []
    # thick light lines, each spp its own pattern (thin dark dashes are the fronts)
    dashes = [(0, (1, 1)), (0, (4, 1, 1, 1)), (0, (8, 2)), "-", (0, (2, 2, 6, 2))]
    for si, spp in enumerate(spps):
        for meth in methods:
            v = m.get((meth, spp))
            if v:
                colour, hollow = style[meth]
                points.append((v["ms"], v[metric], meth, spp, colour, SPP_MARKERS[si % len(SPP_MARKERS)], hollow))
        v = m.get((INPUT, spp))
        if v:
            lines.append((v[metric], spp, dashes[si % len(dashes)]))
    return points, lines


def chart(m, metric, ylabel, path, oidn=None):
    points, lines = chart_layout(m, metric)
    spps = sorted({k[1] for k in m})
    fig, ax = plt.subplots(figsize=(10, 5.5))
    for ms, val, meth, spp, colour, marker, hollow in points:
        auto = meth.startswith("auto")  # the default: outlined so it can be found on the front
        first = spp == spps[0] or not any(p[2] == meth and p[3] < spp for p in points)
        ax.scatter(ms, val, marker=marker, s=45, zorder=3, linewidths=1.2,
                   facecolors="none" if hollow else colour, edgecolors="k" if auto else colour,
                   label=meth if first else None)
    for spp in spps:
        front = pareto([(p[0], p[1], p[2]) for p in points if p[3] == spp])
        ax.plot([p[0] for p in front], [p[1] for p in front], color="0.5", lw=1, ls="--", zorder=2)
        if front:
            ax.annotate(f"{spp} spp", (front[-1][0], front[-1][1]), textcoords="offset points", xytext=(6, 0),
                        fontsize=8, color="0.3")
    for val, spp, dash in lines:
        ax.axhline(val, color="0.65", lw=1.8, ls=dash, zorder=1)
        ax.annotate(f"input {spp} spp", (0.005, val), xycoords=("axes fraction", "data"), textcoords="offset points",
                    xytext=(0, 2), fontsize=7, color="0.3")
    for si, spp in enumerate(sorted(oidn or {})):
        val = oidn[spp][0]
        ax.axhline(val, color="#d62728", lw=1.2, ls=(0, (6, 3)), zorder=1, alpha=0.8)
        ax.annotate(f"OIDN {spp} spp (anchor)", (0.995, val), xycoords=("axes fraction", "data"),
                    textcoords="offset points", xytext=(0, 2), fontsize=7, color="#d62728", ha="right")
    ax.set_xscale("log")
    ax.set_xlabel("time per frame (ms, log scale; fastest of repeated runs)")
    ax.set_ylabel(ylabel)
    ax.set_title(f"{ylabel} against time (mean over scenes); dashed: Pareto front per spp; "
                 "lines: the noisy input" + ("; red: OIDN" if oidn else ""), fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    for si, spp in enumerate(spps):
        handles.append(plt.Line2D([], [], color="k", marker=SPP_MARKERS[si % len(SPP_MARKERS)], ls=""))
        labels.append(f"{spp} spp")
    ax.legend(handles, labels, fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_summary(m, path, oidn=None):
    gap = bool(oidn)
    with open(path, "w") as f:
        f.write("| method | spp | scenes | PSNR dB | SSIM | relMSE | SMAPE | ms/frame |" +
                (" PSNR - OIDN |\n" if gap else "\n"))
        f.write("|---|---:|---:|---:|---:|---:|---:|---:|" + ("---:|\n" if gap else "\n"))
        for (meth, spp), v in sorted(m.items(), key=lambda kv: (kv[0][1], kv[1]["ms"])):
            f.write(f"| {meth} | {spp} | {v['n']} | {v['psnr']:.2f} | {v['ssim']:.4f} | {v['relmse']:.4g} | "
                    f"{v['smape']:.4f} | {v['ms']:.2f} |")
            if gap:
                o = oidn.get(spp)
                f.write(f" {v['psnr'] - o[0]:+.2f} |" if o and o[1] == v["n"] else " |")
            f.write("\n")
        if gap:
            f.write("\nOIDN (anchor, not run here): " +
                    ", ".join(f"{spp} spp {o[0]:.2f} dB ({o[1]} scenes)" for spp, o in sorted(oidn.items())) + "\n")


def write_scenes(rows, path):
    with open(path, "w") as f:
        f.write("| scene | spp | method | PSNR dB | SSIM | ms |\n|---|---:|---|---:|---:|---:|\n")
        for r in sorted(rows, key=lambda r: (r["scene"], r["spp"], r["ms"])):
            f.write(f"| {r['scene']} | {r['spp']} | {r['method']} | {r['psnr']:.2f} | {r['ssim']:.4f} | {r['ms']:.2f} |\n")


def harm_table(rows):
    """Markdown: per method and spp, output minus input (worst, mean, scenes
    below the input) and, on firefly scenes, luminance ratio and peak."""
    inp = {(r["scene"], r["frame"], r["spp"]): r["psnr"] for r in rows if r["method"] == "input"}
    acc = defaultdict(list)
    ff = defaultdict(list)
    for r in rows:
        key = (r["scene"], r["frame"], r["spp"])
        if r["method"] == "input" or key not in inp:
            continue
        acc[(r["method"], r["spp"])].append((r["psnr"] - inp[key], r["scene"]))
        if "firefly" in r["scene"]:
            ff[(r["method"], r["spp"])].append((r["lum_ratio"], r["peak"]))
    lines = ["| method | spp | worst out - in dB | scene | mean out - in dB | below input | "
             "firefly lum ratio | firefly peak |",
             "|---|---:|---:|---|---:|---:|---:|---:|"]
    for (meth, spp), v in sorted(acc.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        worst = min(v)
        below = sum(1 for d, _ in v if d < 0)
        f = ff.get((meth, spp), [])
        lum = ", ".join(f"{a:.2f}" for a, _ in f) or "-"
        peak = ", ".join(f"{b:.1f}" for _, b in f) or "-"
        lines.append(f"| {meth} | {spp} | {worst[0]:+.2f} | {worst[1]} | {sum(d for d, _ in v) / len(v):+.2f} | "
                     f"{below}/{len(v)} | {lum} | {peak} |")
    return "\n".join(lines) + "\n"


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


def write_temporal(out):
    """OUT_DIR/temporal.csv (edgewise bench --temporal) -> temporal.md (mean over scenes per method, spp and
    accumulation mode, then per scene), temporal_psnr_vs_flicker.png, and the mean table on stdout.
    Returns False when there is no temporal.csv."""
    path = os.path.join(out, "temporal.csv")
    if not os.path.isfile(path):
        return False
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    keys = ("psnr", "ssim", "tdiff", "tdiff_ref", "tdiff_excess", "flicker_static", "static_frac", "ms")
    for r in rows:
        for k in keys:
            r[k] = float(r[k])
        r["spp"] = int(r["spp"])
    modes = ["off", "after", "after-demod", "before-demod"]
    order = {m: i for i, m in enumerate(modes)}
    acc = defaultdict(lambda: defaultdict(list))
    for r in rows:
        for k in keys:
            acc[(r["spp"], r["method"], r["accumulation"])][k].append(r[k])
    mean = {g: {k: sum(v) / len(v) for k, v in a.items()} | {"n": len(a["psnr"])} for g, a in acc.items()}
    head = ("| spp | method | accumulation | scenes | PSNR dB | SSIM | tdiff | tdiff ref | excess | static flicker | "
            "ms/frame |\n|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n")
    lines = [f"# Temporal stability ({len({r['scene'] for r in rows})} sequences)\n",
             "tdiff: mean |change| of the tone-mapped output between consecutive frames; excess: tdiff minus the "
             "reference's (flicker added, < 0: smoother in time than the reference); static flicker: tdiff over "
             "pixels whose reference and motion are still.\n", "## Mean over scenes\n", head]
    for g, v in sorted(mean.items(), key=lambda kv: (kv[0][0], kv[0][1], order.get(kv[0][2], 9))):
        lines.append(f"| {g[0]} | {g[1]} | {g[2]} | {v['n']} | {v['psnr']:.2f} | {v['ssim']:.4f} | {v['tdiff']:.5f} | "
                     f"{v['tdiff_ref']:.5f} | {v['tdiff_excess']:+.5f} | {v['flicker_static']:.6f} | {v['ms']:.1f} |\n")
    print("".join(lines[2:]), end="")
    lines += ["\n## Per scene\n", head.replace("| spp |", "| scene | spp |", 1).replace("|---:|---|", "|---|---:|---|", 1)]
    for r in sorted(rows, key=lambda r: (r["scene"], r["spp"], r["method"], order.get(r["accumulation"], 9))):
        lines.append(f"| {r['scene']} | {r['spp']} | {r['method']} | {r['accumulation']} | 1 | {r['psnr']:.2f} | "
                     f"{r['ssim']:.4f} | {r['tdiff']:.5f} | {r['tdiff_ref']:.5f} | {r['tdiff_excess']:+.5f} | "
                     f"{r['flicker_static']:.6f} | {r['ms']:.1f} |\n")
    with open(os.path.join(out, "temporal.md"), "w") as f:
        f.write("".join(lines))
    spps = sorted({g[0] for g in mean})
    methods = sorted({g[1] for g in mean})
    cmap = plt.get_cmap("tab10")
    markers = {"off": "o", "after": "s", "after-demod": "D", "before-demod": "^"}
    fig, axes = plt.subplots(1, len(spps), figsize=(6.5 * len(spps), 5), squeeze=False)
    for ax, spp in zip(axes[0], spps):
        for mi, meth in enumerate(methods):
            pts = [(mode, mean[(spp, meth, mode)]) for mode in modes if (spp, meth, mode) in mean]
            if not pts:
                continue
            ax.plot([v["tdiff_excess"] for _, v in pts], [v["psnr"] for _, v in pts], color=cmap(mi % 10), lw=0.8,
                    alpha=0.6)
            for mode, v in pts:
                ax.scatter(v["tdiff_excess"], v["psnr"], color=cmap(mi % 10), marker=markers.get(mode, "x"), s=40,
                           zorder=3, label=meth if mode == "off" else None)
        ax.axvline(0.0, color="0.5", lw=0.8, ls="--")
        ax.set_xscale("symlog", linthresh=1e-3)
        ax.set_xlabel("excess frame-to-frame change over the reference (tone-mapped; 0 = as stable)")
        ax.set_ylabel("PSNR (dB), mean over frames and scenes")
        ax.set_title(f"{spp} spp")
        ax.grid(True, alpha=0.3)
    handles, labels = axes[0][0].get_legend_handles_labels()
    for mode, mk in markers.items():
        handles.append(plt.Line2D([], [], color="k", marker=mk, ls=""))
        labels.append(f"accumulation {mode}")
    axes[0][-1].legend(handles, labels, fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "temporal_psnr_vs_flicker.png"), dpi=110)
    plt.close(fig)
    print(f"bench_report: wrote {out}/temporal.md and temporal_psnr_vs_flicker.png")
    return True


def main(argv):
    if len(argv) < 2 or argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        return 0 if len(argv) == 2 else 2
    oidn_path = None
    if "--oidn" in argv:
        i = argv.index("--oidn")
        if i + 1 >= len(argv):
            print("bench_report: --oidn needs the anchor file", file=sys.stderr)
            return 2
        oidn_path = argv[i + 1]
        argv = argv[:i] + argv[i + 2:]
        if not os.path.isfile(oidn_path):
            print(f"bench_report: no anchor file {oidn_path}", file=sys.stderr)
            return 1
    if len(argv) != 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    out = argv[1]
    if write_temporal(out) and not os.path.isfile(os.path.join(out, "results.csv")):
        return 0  # a --temporal run only
    path = os.path.join(out, "results.csv")
    if not os.path.isfile(path):
        print(f"bench_report: no {path} (run 'edgewise bench DATA -o {out}' first)", file=sys.stderr)
        return 1
    rows = load(path)
    if not rows:
        print(f"bench_report: {path} has no rows", file=sys.stderr)
        return 1
    m = means(rows)
    oidn = load_oidn(oidn_path, rows) if oidn_path else None
    chart(m, "psnr", "PSNR (dB)", os.path.join(out, "psnr_vs_ms.png"), oidn)
    chart(m, "ssim", "SSIM", os.path.join(out, "ssim_vs_ms.png"))
    write_summary(m, os.path.join(out, "summary.md"), oidn)
    write_scenes(rows, os.path.join(out, "scenes.md"))
    harm = harm_table(rows)
    with open(os.path.join(out, "harm.md"), "w") as f:
        f.write(harm)
    print(harm, end="")
    page = write_html(rows, out)
    print(f"bench_report: wrote charts and tables to {out}" + (" and index.html" if page else ""))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
