#!/usr/bin/env python3
"""The tables of README.md from the caches of an acceptance run (issue 13).

    python3 make-table.py [FOLDER]    FOLDER holds *.cache.jsonl (default: this script's folder)

Prints, as Markdown:
  1. the fastest verified variant (status "ok": verified against the float64 gold and within
     the run's error budget) per API, data set and weight format: ms per frame (the timing's
     median) and x = time / the same-size copy (`x_copy`); rows are f32 and the narrowest
     format verified in some API (unorm8 where it is within budget, else unorm16);
  2. the OpenCL/CUDA twins (the same variant key apart from the language, both verified) at
     1600k-b1/b4/b8 and 6400k-b4: OpenCL time / CUDA time, the winners' twins and the spread
     over every pair;
  3. issue 13's Done-when targets, each met or missed and by how much.
"""
import glob
import json
import os
import statistics
import sys

DATASETS = ["400k-b4", "1600k-b1", "1600k-b4", "1600k-b8", "6400k-b4"]
APIS = [("opencl", "OpenCL"), ("cuda", "CUDA"), ("glsl-compute", "GLSL compute"), ("vulkan", "Vulkan")]
FORMATS = ["f32", "unorm16", "unorm8"]  # widest first
TWIN_DATASETS = ["1600k-b1", "1600k-b4", "1600k-b8", "6400k-b4"]


def load(folder):
    rows = []
    for path in sorted(glob.glob(os.path.join(folder, "*.cache.jsonl"))):
        with open(path) as f:
            rows += [json.loads(line) for line in f if line.strip()]
    return [r for r in rows if r["dataset"] in DATASETS]


def fastest(rows):
    """(lang, dataset, weight) -> the fastest verified measurement."""
    best = {}
    for r in rows:
        if r["status"] != "ok":
            continue
        v = r["variant"]
        k = (v["lang"], r["dataset"], v["weight"])
        if k not in best or r["timing"]["median_ms"] < best[k]["timing"]["median_ms"]:
            best[k] = r
    return best


def cell(r):
    return "%.4f (x%.2f)" % (r["timing"]["median_ms"], r["x_copy"]) if r else "-"


def main_table(best):
    out = ["| data set | format | " + " | ".join(n for _, n in APIS) + " |",
           "|---|---|" + "---|" * len(APIS)]
    for d in DATASETS:
        verified = [w for w in FORMATS if any((l, d, w) in best for l, _ in APIS)]
        for w in verified[:1] + verified[-1:] if len(verified) > 1 else verified:
            out.append("| %s | %s | " % (d, w) + " | ".join(cell(best.get((l, d, w))) for l, _ in APIS) + " |")
    return out


def twins(rows):
    """dataset -> {key without the language: (opencl row, cuda row)}"""
    by = {}
    for r in rows:
        v = r["variant"]
        if r["status"] != "ok" or v["lang"] not in ("opencl", "cuda") or r["dataset"] not in TWIN_DATASETS:
            continue
        by.setdefault(r["dataset"], {}).setdefault(v["key"].split(".", 1)[1], {})[v["lang"]] = r
    return {d: {k: (p["opencl"], p["cuda"]) for k, p in keys.items() if len(p) == 2} for d, keys in by.items()}


def ms(r):
    return r["timing"]["median_ms"]


def twin_table(pairs, best):
    out = ["| data set | winner's twin (format) | OpenCL ms | CUDA ms | OpenCL / CUDA | pairs | median ratio | range | within 3% |",
           "|---|---|---|---|---|---|---|---|---|"]
    for d in TWIN_DATASETS:
        ps = pairs.get(d, {})
        ratios = [ms(a) / ms(b) for a, b in ps.values()]
        # The twins of each language's winner in the narrowest verified format (if measured in both).
        shown = []
        for lang in ("opencl", "cuda"):
            for w in reversed(FORMATS):
                r = best.get((lang, d, w))
                if r:
                    k = r["variant"]["key"].split(".", 1)[1]
                    if k in ps and k not in [s[0] for s in shown]:
                        shown.append((k, w))
                    break
        summary = "%d | %.3f | %.3f-%.3f | %d" % (len(ratios), statistics.median(ratios), min(ratios), max(ratios),
                                               sum(abs(x - 1) <= 0.03 for x in ratios)) if ratios else "0 | - | - | -"
        if not shown:
            out.append("| %s | (no winner measured in both) | - | - | - | %s |" % (d, summary))
        for i, (k, w) in enumerate(shown):
            a, b = ps[k]
            out.append("| %s | `%s` (%s) | %.4f | %.4f | %.3f | %s |" %
                       (d, k, w, ms(a), ms(b), ms(a) / ms(b), summary if i == 0 else "| | |"))
    return out


def targets(best, pairs):
    """Issue 13's Done-when targets: the winners are each API's fastest verified variant per data set
    (any format within budget)."""
    win = {}
    for (l, d, w), r in best.items():
        if (l, d) not in win or ms(r) < ms(win[(l, d)]):
            win[(l, d)] = r
    out = ["| target | case | measured | limit | verdict |", "|---|---|---|---|---|"]

    def row(name, case, x, limit):
        verdict = "met (%.0f%% under)" % ((limit - x) / limit * 100) if x <= limit else \
            "**missed by %.1f%%**" % ((x - limit) / limit * 100)
        out.append("| %s | %s | x%.3f | x%.2f | %s |" % (name, case, x, limit, verdict))

    for lang, name in (("opencl", "OpenCL"), ("cuda", "CUDA")):
        for d in DATASETS:
            r = win.get((lang, d))
            if r:
                row(name + " winner / same-size copy", "%s (%s)" % (d, r["variant"]["weight"]), r["x_copy"],
                    1.15 if d.startswith("400k") else 1.05)
    for d in DATASETS[1:]:
        r = win.get(("glsl-compute", d))
        if r:
            row("GLSL compute winner / same-size copy", "%s (%s)" % (d, r["variant"]["weight"]), r["x_copy"], 1.10)
    for d in TWIN_DATASETS:
        ps = pairs.get(d, {})
        # The winners' twins: each language's winner, where the other language measured the same key.
        keys = {win[(l, d)]["variant"]["key"].split(".", 1)[1] for l in ("opencl", "cuda") if (l, d) in win}
        wr = [ms(ps[k][0]) / ms(ps[k][1]) for k in sorted(keys) if k in ps]
        if wr:
            ok = all(abs(x - 1) <= 0.03 for x in wr)
            out.append("| OpenCL/CUDA twins within 3%% | %s, the winners' twins (%d) | %s | 0.97-1.03 | %s |" %
                       (d, len(wr), ", ".join("%.3f" % x for x in wr), "met" if ok else "**missed**"))
        ratios = [ms(a) / ms(b) for a, b in ps.values()]
        if ratios:
            worst = max(ratios, key=lambda x: abs(x - 1))
            inside = sum(abs(x - 1) <= 0.03 for x in ratios)
            verdict = "met" if inside == len(ratios) else \
                "**missed**: %d of %d outside, worst %+.1f%%" % (len(ratios) - inside, len(ratios), (worst - 1) * 100)
            out.append("| OpenCL/CUDA twins within 3%% | %s, every pair measured in both (%d) | %.3f-%.3f (median %.3f) | 0.97-1.03 | %s |" %
                       (d, len(ratios), min(ratios), max(ratios), statistics.median(ratios), verdict))
    return out


def main():
    folder = sys.argv[1] if len(sys.argv) > 1 else os.path.dirname(os.path.abspath(__file__))
    rows = load(folder)
    best = fastest(rows)
    pairs = twins(rows)
    print("\n".join(main_table(best)))
    print()
    print("\n".join(twin_table(pairs, best)))
    print()
    print("\n".join(targets(best, pairs)))


if __name__ == "__main__":
    main()
