#!/usr/bin/env python3
"""Summaries of bench/kernel-time/run.sh's outputs.

  compare.py ncu LAUNCHES OUT SIZE...
                                  skintune's kernel time against Nsight Compute's gpu__time_duration of the last
                                  LAUNCHES cold frames of each variant (the bench's --launches), per variant and size
  compare.py runs REPORT...       the chosen winners of several `skintune run` reports: agreement, tie sets, spread
  compare.py twins OUT            one variant's kernel time in each language, per size
  compare.py turns LOG...         each run's devices from its SKINTUNE_TIMING_LOG: when each turn ran, the chip's
                                  turns against the host's CPU devices (which ended last, by how much), the gaps
                                  between the chip's turns, the host lock's waits, the workers' discovery, and
                                  each device's race warm-ups
  compare.py choice MARGIN REPORT...
                                  the runs' agreement were each row's last race to choose its winner among
                                  the candidates within MARGIN of the fastest (GPU rows, judged as
                                  tuner/statistics.cpp TiedAt does; host rows as the report picked them:
                                  within host_tie_margin, plus host_process_spread where
                                  host_choose_in_tie_set, less the race's separated where
                                  host_choose_unseparated): what a choice wider or narrower than the report's costs.
                                  MARGIN = tie_margin + process_spread is the GPU's default choice, its tie set
"""
import csv, glob, json, os, re, statistics, sys


def by_variant(rows, variants, path):
    """Nsight Compute's rows of one process split by variant: each variant's kernels
    follow each other, its verification launch, its warm-up (as many as the clock
    took) and its cold frames, and neighbours differ in block size (run.sh ncu's
    list). The last `launches` of each are its cold frames."""
    if not rows:
        return []
    segments = [[rows[0]]]
    for r in rows[1:]:
        if r["Block Size"] == segments[-1][-1]["Block Size"]:
            segments[-1].append(r)
        else:
            segments.append([r])
    if len(segments) != variants:
        sys.exit("%s: %d runs of one block size for %d variants: neighbouring variants must differ in block size"
                 % (path, len(segments), variants))
    return segments


def ncu(out, sizes, launches):
    print("size      variant                                                               skintune us   ncu us   ratio")
    worst = 0.0
    for size in sizes:
        ours = [json.loads(l) for l in open(os.path.join(out, "skintune-%s.jsonl" % size)) if l.strip()]
        rows = []
        path = os.path.join(out, "ncu-%s.csv" % size)
        if os.path.exists(path):
            lines = [l for l in open(path) if l.startswith('"')]
            rows = [r for r in csv.DictReader(lines) if r.get("Metric Name") == "gpu__time_duration.sum"]
        segments = by_variant(rows, len(ours), path)
        keys = [m["variant"]["key"] for m in ours]
        for i, m in enumerate(ours):
            key = m["variant"]["key"]
            # A variant measured again later in the process: this is its warm-up, the
            # process's first kernels (run.sh ncu), shown and not counted.
            warm_up = key in keys[i + 1:]
            mine = m["timing"]["median_ms"] * 1e3
            theirs = [float(r["Metric Value"].replace(",", "")) / 1e3 for r in segments[i][-launches:]] if segments else []
            if not theirs:
                print("%-9s %-70s %10.3f        -       -" % (size, key, mine))
                continue
            t = statistics.median(theirs)
            if not warm_up:
                worst = max(worst, abs(mine / t - 1))
            print("%-9s %-70s %10.3f %8.3f %7.3f%s" % (size, key, mine, t, mine / t,
                                                     "  (first in the process, again below: not counted)" if warm_up else ""))
    print("largest |skintune / ncu - 1|: %.3f" % worst)


def chosen(report):
    r = json.load(open(report))
    rows = {}
    for w in r["winners"]:
        if w.get("chosen"):
            rows[(w["device_id"], w["lang"], w["dataset"])] = w
    return rows


def launch_starts(report):
    """Each (device, dataset, variant key)'s launch start (timing.launch_start_ms), ms."""
    return {(m["device_id"], m["dataset"], m["variant"]["key"]): m["timing"].get("launch_start_ms", 0.0)
            for m in json.load(open(report))["measurements"] if "timing" in m}


def sm_clocks(report):
    """Each (device, dataset, variant key)'s lowest SM clock around its batches (timing.sm_clock_mhz; 0: not read)."""
    return {(m["device_id"], m["dataset"], m["variant"]["key"]): m["timing"].get("sm_clock_mhz", 0)
            for m in json.load(open(report))["measurements"] if "timing" in m}


def runs(reports):
    all_rows = [chosen(p) for p in reports]
    starts = [launch_starts(p) for p in reports]
    clocks = [sm_clocks(p) for p in reports]
    keys = sorted(set().union(*[set(r) for r in all_rows]))
    same = compatible = 0
    worst_spread = 1.0
    within = {}  # language: [rows the same and within 3%, rows]
    for k in keys:
        ws = [r.get(k) for r in all_rows]
        if any(w is None for w in ws):
            print("missing in a run:", k)
            continue
        names = [w["variant"]["key"] for w in ws]
        times = [w["median_ms"] for w in ws]
        spread = max(times) / min(times)
        worst_spread = max(worst_spread, spread)
        if len(set(names)) == 1:
            same += 1
        else:
            ok = all(n in w["tie_set"] for n in names for w in ws)
            compatible += ok
            print("differ%s: %s %s %s: %s" % (" (each in the others' tie sets)" if ok else "", k[0][:40], k[1], k[2],
                                             ", ".join("%s %.2f us" % (n.split(".", 2)[2], t * 1e3) for n, t in zip(names, times))))
        # The winners' contexts' launch starts (0 where none was probed: the host's CPU).
        ls = [st.get((k[0], k[2], n), 0.0) for st, n in zip(starts, names)]
        if spread > 1.03:
            # How much of the spread is the context's, or the clock's.
            mhz = [st_clock.get((k[0], k[2], n), 0) for st_clock, n in zip(clocks, names)]
            print("spread %.3f: %s %s %s: %s" % (spread, k[0][:40], k[1], k[2], ", ".join(
                "%.2f us (launch start %.2f, SM clock %s MHz)" % (t * 1e3, l * 1e3, c or "-")
                for t, l, c in zip(times, ls, mhz))))
        # As if every run's context had the same launch start (their mean): how much of the
        # spread is the contexts'.
        same_start = [t - l + sum(ls) / len(ls) for t, l in zip(times, ls)]
        beyond_spread = max(same_start) / min(same_start)
        api = "%s on %s" % (k[1], k[0].split("/")[0])
        within.setdefault(api, [0, 0, 0])
        within[api][0] += len(set(names)) == 1 and spread <= 1.03
        within[api][1] += len(set(names)) == 1 and beyond_spread <= 1.03
        within[api][2] += 1
    n = len(keys)
    print("rows: %d; the same winner in every run: %d (%.0f%%); differing but within each other's tie sets: %d; "
          "largest winner time ratio across runs: %.3f" % (n, same, 100.0 * same / max(n, 1), compatible, worst_spread))
    over = 0
    for p in reports:
        r = json.load(open(p))
        for m in r["measurements"]:
            if m["status"] == "invalid" and "impossible kernel time" in m.get("detail", ""):
                over += 1
    print("measurements rejected over the ceiling: %d" % over)
    print("the same winner within 3%: " + ", ".join("%s %d of %d" % (a, w, n) for a, (w, _, n) in sorted(within.items())))
    print("the same winner within 3% were the contexts' launch starts the same: " +
          ", ".join("%s %d of %d" % (a, b, n) for a, (_, b, n) in sorted(within.items())))


STORAGE_LIMITS = {"global": 0, "constant": 1, "local": 2, "image": 3}  # tuner/statistics.h StorageLimits


def choice(margin, reports):
    """Each run's last race per row, its winner chosen again: the tie-break rule (fewest bytes, then
    the lower error, then the storage's limits, then the key) among the candidates within `margin` (GPU) of the fastest, as
    TiedAt judges them. At margin = tie_margin this is the contenders' choice, at tie_margin +
    process_spread the tie set's (the row's final judgement may also come from intervals where no
    race ran)."""
    picks, cost = {}, []
    for i, p in enumerate(reports):
        r = json.load(open(p))
        measured = {(m["device_id"], m["dataset"], m["variant"]["key"]): m for m in r["measurements"] if m["status"] == "ok"}
        host_margin = r.get("host_tie_margin", 0.25)
        host_unseparated = r.get("host_choose_in_tie_set", False) and r.get("host_choose_unseparated", False)
        if r.get("host_choose_in_tie_set", False):
            host_margin += r.get("host_process_spread", 0.0)
        for race in r["races"]:
            host = race["device_id"].startswith("cpu:") or "Portable" in race["device_id"]
            allowed = host_margin if host else margin
            fastest = next(e for e in race["entries"] if e["verdict"] == "fastest")

            def rule(e):  # TieBreak: bytes, error, storage limits (StorageLimits), key
                m = measured.get((race["device_id"], race["dataset"], e["variant"]), {})
                limits = STORAGE_LIMITS.get(m.get("variant", {}).get("storage", "global"), 3)
                return (m.get("bytes_per_frame", float("inf")), m.get("source_error", {}).get("position_rel", 0.0),
                        limits, e["variant"])
            # TiedAt: the fastest, and each entry whose median, or whole interval, is within the margin.
            pool = [e for e in race["entries"] if e is fastest or e["median_ms"] <= fastest["median_ms"] * (1 + allowed)
                    or e["high_ms"] <= fastest["low_ms"] * (1 + allowed)]
            if host and host_unseparated:  # Choice::kTieSetUnseparated: less those separated at the margin
                pool = [e for e in pool if e is fastest or e["verdict"] != "slower"]
            winner = min(pool, key=rule)
            picks.setdefault((race["device_id"], race["lang"], race["dataset"]), [None] * len(reports))[i] = winner["variant"]
            if not host:
                cost.append(winner["median_ms"] / fastest["median_ms"])
    same = sum(1 for v in picks.values() if None not in v and len(set(v)) == 1)
    gpu = [v for k, v in picks.items() if not (k[0].startswith("cpu:") or "Portable" in k[0])]
    print("GPU rows %d, the same winner in every run %d" % (len(gpu), sum(1 for v in gpu if None not in v and len(set(v)) == 1)))
    cost.sort()
    print("choice margin %.3f: rows %d, the same winner in every run %d; GPU winners against their race's fastest: "
          "median %.3f, p90 %.3f, largest %.3f" % (margin, len(picks), same, statistics.median(cost),
                                                   cost[int(0.9 * len(cost))], cost[-1]))


def twins(out):
    """Each size's kernel time per language, then the same less each context's
    launch start (timing.launch_start_ms: a 4 KiB copy's kernel time): the
    kernel beyond the smallest launch; then the frame time (timing.frame_ms,
    Skin() back to back, which no device stamp touches: an API whose launch
    starts later on the device is slower there too). max/min over OpenCL,
    CUDA and Vulkan."""
    by = {}
    for path in glob.glob(os.path.join(out, "twins-*.jsonl")):
        for l in open(path):
            if l.strip():
                m = json.loads(l)
                by.setdefault(m["dataset"], {})[m["variant"]["lang"]] = m["timing"]
    langs = ("opencl", "cuda", "vulkan", "glsl-compute")
    figures = (("kernel time, us", lambda t: t["median_ms"] * 1e3),
               ("launch start, us", lambda t: t.get("launch_start_ms", 0) * 1e3),
               ("beyond the launch start, us", lambda t: (t["median_ms"] - t.get("launch_start_ms", 0)) * 1e3),
               ("frame time, us", lambda t: t.get("frame_ms", 0) * 1e3))
    for title, figure in figures:
        print(title)
        print("size       " + "  ".join("%12s" % l for l in langs) + "   max/min (opencl, cuda, vulkan)")
        for size in sorted(by, key=lambda s: float(s.split("k")[0])):
            t = {l: figure(by[size][l]) for l in by[size]}
            vals = [t[l] for l in ("opencl", "cuda", "vulkan") if l in t and t[l] > 0]
            ratio = "%.3f" % (max(vals) / min(vals)) if vals else "-"
            print("%-10s " % size + "  ".join("%12s" % ("%.2f" % t[l] if l in t else "-") for l in langs)
                  + "   " + ratio)
        print()


def is_host_cpu(device):
    # The timing log's device names: "cpu <model>" (skintune's cpu device), "opencl cpu-..." or
    # "opencl pthread-..." (PoCL's CPU device); every other is a GPU's API.
    return device.startswith("cpu ") or device.startswith("opencl cpu-") or device.startswith("opencl pthread-")


def turns(logs):
    for path in logs:
        spans, waits = [], {"CPU device's timed work": [], "GPU worker's host work": []}
        found = {}  # "every API's" or one API's discovery in a worker: its times, ms
        warmed = {}  # each device's races: their warm-ups in the process that raced, ms
        origin = None
        for line in open(path):
            stamp, _, text = line.rstrip("\n").partition(" ")
            t = float(stamp)
            origin = t if origin is None else origin
            m = re.match(r"(.+) device: ([\d.]+) ms$", text)
            if m:
                spans.append((t - float(m.group(2)) / 1000 - origin, t - origin, m.group(1)))
            m = re.match(r"host lock: a (.+) waited ([\d.]+) ms", text)
            if m and m.group(1) in waits:
                waits[m.group(1)].append(float(m.group(2)))
            m = re.match(r"tune-worker .*: (every API's|\S+'s) devices found in (\d+) ms", text)
            if m:
                found.setdefault(m.group(1), []).append(float(m.group(2)))
            m = re.match(r"(.+) race of \d+ for \S+ in this process: prepared in \d+ ms, warmed in (\d+) ms", text)
            if m:
                warmed.setdefault(m.group(1), []).append(float(m.group(2)))
        print(path + " (seconds from the log's first line)")
        for start, end, device in sorted(spans):
            print("  %-60s %6.1f - %6.1f  %5.1f%s" % (device[:60], start, end, end - start,
                                                     "  host" if is_host_cpu(device) else ""))
        chip = sorted(s for s in spans if not is_host_cpu(s[2]))
        host = [s for s in spans if is_host_cpu(s[2])]
        if chip and host:
            chip_end, host_end = max(s[1] for s in chip), max(s[1] for s in host)
            print("  last: %s, %.1f s after the %s" % ("the host's CPU devices" if host_end > chip_end else "the chip's turns",
                                                    abs(host_end - chip_end),
                                                    "chip's turns" if host_end > chip_end else "host's CPU devices"))
        if len(chip) > 1:
            print("  between the chip's turns: " + ", ".join("%.2f" % (b[0] - a[1]) for a, b in zip(chip, chip[1:])) + " s")
        for who, ms in waits.items():
            if ms:
                print("  host lock: a %s waited %d times, %.0f ms in all, the longest %.0f" % (who, len(ms), sum(ms), max(ms)))
        for what, ms in sorted(found.items()):
            print("  workers that found %s devices: %d, %.0f ms in all, median %.0f, the longest %.0f"
                  % (what, len(ms), sum(ms), statistics.median(ms), max(ms)))
        for device, ms in sorted(warmed.items()):
            print("  %s: %d races, warmed in %.0f ms in all, the longest %.0f, %d over 300 ms"
                  % (device[:60], len(ms), sum(ms), max(ms), sum(1 for x in ms if x > 300)))


if __name__ == "__main__":
    mode = sys.argv[1]
    if mode == "ncu":
        ncu(sys.argv[3], sys.argv[4:], int(sys.argv[2]))
    elif mode == "runs":
        runs(sys.argv[2:])
    elif mode == "twins":
        twins(sys.argv[2])
    elif mode == "turns":
        turns(sys.argv[2:])
    elif mode == "choice":
        choice(float(sys.argv[2]), sys.argv[3:])
    else:
        sys.exit("unknown mode " + mode)
