"""Statistics for run/bench_fwi.sh: medians of the wall-clock and -log_view measurements it left
in OUT, printed as markdown.

    /usr/bin/python3 run/bench_fwi.py OUT

Definitions (per rank count and parameter set, all medians over the repetitions):
  wall clock   forward solve = forward run - startup run;   gradient = gradient run - forward run
  -log_view    forward solve = TSStep of the forward run (5000 steps);
               gradient = Main Stage time of the gradient run - that of the forward run
               (the gradient run = setup + synthetic-data forward + one gradient; the forward run =
               setup + one forward, so the difference is one gradient evaluation)
  ratio        gradient / forward solve;  target from the issue: <= 2.5
Times from -log_view are the maximum over ranks.
"""
import csv
import os
import statistics
import sys
from collections import defaultdict

EVENTS = ["TSStep", "TSFunctionEval", "TSTrajectorySet", "TSTrajectoryGet", "TSAdjointStep", "MatMult",
          "MatMultTranspose", "VecCopy", "VecMAXPY", "VecScatterBegin", "VecScatterEnd"]
TASKS = ("startup", "forward", "gradient")


def parse_log_view(path):
    """{'Main': total time, event: max time} from one -log_view output (first stage only)."""
    out = {}
    in_events = False
    with open(path) as f:
        for line in f:
            w = line.split()
            if line.startswith("Time (sec):"):
                out["Main"] = float(w[2])
            elif line.startswith("--- Event Stage 0"):
                in_events = True
            elif line.startswith("--- Event Stage") and in_events:
                break
            elif in_events and len(w) > 4 and w[0] in EVENTS and w[0] not in out:
                out[w[0]] = float(w[3])
                out[w[0] + ":count"] = float(w[1])
    if "Main" not in out:
        raise ValueError(f"{path}: no -log_view summary")
    return out


def med(xs):
    return statistics.median(xs) if xs else float("nan")


def main(out):
    meta, commands = {}, {}
    with open(os.path.join(out, "meta.tsv")) as f:
        for line in f:
            k, _, v = line.rstrip("\n").partition("\t")
            if k == "command":
                n, p, t, cmd = v.split("\t", 3)
                commands[(n, p, t)] = cmd
            elif k == "failed_run":
                meta.setdefault("failed", []).append(v)
            else:
                meta[k] = v
    wall = defaultdict(list)
    with open(os.path.join(out, "wall.tsv")) as f:
        for row in csv.DictReader(f, delimiter="\t"):
            wall[(row["nprocs"], row["params"], row["task"])].append(float(row["wall_s"]))
    logs = defaultdict(lambda: defaultdict(list))
    rss = defaultdict(list)
    for name in sorted(os.listdir(out)):
        if name.endswith(".log_view.txt") or name.endswith(".rss_kb"):
            stem = name.split(".")[0]
            n, p, t, _ = stem.split("_")
            key = (n[2:], p, t)
            if name.endswith(".log_view.txt"):
                for k, v in parse_log_view(os.path.join(out, name)).items():
                    logs[key][k].append(v)
            else:
                with open(os.path.join(out, name)) as f:
                    lines = [x for x in f.read().split() if x.isdigit()]
                if lines:
                    rss[key].append(int(lines[-1]) / 1024.0)
    configs = sorted({(n, p) for (n, p, _) in wall}, key=lambda c: (int(c[0]), c[1] != "scalar"))
    nparams = {"scalar": "1", "field": "1000"}

    built = f"built from {meta['rev']}" if meta.get("rev") else meta.get("git")
    print(f"Binary {meta.get('binary')} ({built}), {meta.get('host')}, {meta.get('date')}.")
    print(f"{meta.get('reps')} repetitions of each run, interleaved; 1/5/15-minute load average "
          f"{meta.get('load_before')} before, {meta.get('load_after')} after"
          f"{' (waited ' + meta['load_waited_s'] + ' s for it to drop)' if meta.get('load_waited_s', '0') != '0' else ''}.")
    if meta.get("failed"):
        print(f"{len(meta['failed'])} run(s) failed and were repeated: " + "; ".join(meta["failed"]) + ".")
    print()
    print("Wall clock (median seconds of whole `mpiexec ... flexipde` runs):")
    print()
    print("| ranks | parameters | startup run | forward run | gradient run | forward solve = fwd - startup "
          "| gradient = grad - fwd | gradient / forward |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n, p in configs:
        s, fw, g = (med(wall[(n, p, t)]) for t in TASKS)
        F, G = fw - s, g - fw
        ratio = f"**{G / F:.2f}**" if F > 0 else "n/a (start-up noise exceeds the solve)"
        print(f"| {n} | {nparams[p]} | {s:.3f} | {fw:.3f} | {g:.3f} | {F:.3f} | {G:.3f} | {ratio} |")
    print()
    print("-log_view (median seconds, max over ranks):")
    print()
    print("| ranks | parameters | forward solve (TSStep, fwd run) | gradient = Main(grad) - Main(fwd) "
          "| **gradient / forward** | same, fastest runs | same, within each gradient run |")
    print("|---:|---:|---:|---:|---:|---:|---:|")
    breakdown = []
    for n, p in configs:
        L = {t: logs[(n, p, t)] for t in TASKS}
        F = med(L["forward"]["TSStep"])
        G = med(L["gradient"]["Main"]) - med(L["forward"]["Main"])
        best = (min(L["gradient"]["Main"]) - min(L["forward"]["Main"])) / min(L["forward"]["TSStep"])
        # Within one gradient run: a forward solve costs the mean TSStep times the steps of a solve
        # (every TSStep there is a full step: synthetic data, the gradient's forward, re-runs);
        # the gradient is that forward + storing + restoring/re-running + the adjoint steps.
        nsteps = med(L["forward"]["TSStep:count"])
        inrun = []
        for k in range(len(L["gradient"]["Main"])):
            g = {e: L["gradient"][e][k] for e in ("TSStep", "TSStep:count", "TSTrajectorySet", "TSTrajectoryGet",
                                                     "TSAdjointStep")}
            f = g["TSStep"] / g["TSStep:count"] * nsteps
            inrun.append((f + g["TSTrajectorySet"] + g["TSTrajectoryGet"] + g["TSAdjointStep"]) / f)
        print(f"| {n} | {nparams[p]} | {F:.3f} | {G:.3f} | **{G / F:.2f}** | {best:.2f} | {med(inrun):.2f} |")
        ev = {e: med(L["gradient"].get(e, [])) for e in ("Main", "TSStep", "TSTrajectorySet", "TSTrajectoryGet",
                                                          "TSAdjointStep")}
        steps = med(L["gradient"].get("TSStep:count", []))
        m_f, m_g = med(rss[(n, p, "forward")]), med(rss[(n, p, "gradient")])
        breakdown.append(f"| {n} | {nparams[p]} | {ev['Main']:.3f} | {ev['TSStep']:.3f} ({steps:.0f}) "
                         f"| {ev['TSTrajectorySet']:.3f} | {ev['TSTrajectoryGet']:.3f} | {ev['TSAdjointStep']:.3f} "
                         f"| {m_f:.0f} / {m_g:.0f} |")
    print()
    print("Where the gradient run's time goes (-log_view events, median seconds, max over ranks; "
          "TSTrajectoryGet includes the steps re-run to rebuild stages):")
    print()
    print("| ranks | parameters | Main Stage | TSStep (count) | TSTrajectorySet | TSTrajectoryGet | TSAdjointStep "
          "| peak RSS forward / gradient run (MB) |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    for line in breakdown:
        print(line)
    print()
    print("Spread (min-max wall seconds of the gradient runs): " + ", ".join(
        f"{n} rank{'s' if n != '1' else ''}/{nparams[p]} par. {min(wall[(n, p, 'gradient')]):.3f}-"
        f"{max(wall[(n, p, 'gradient')]):.3f}" for n, p in configs))
    print()
    print("Commands (each also run with -log_view):")
    print()
    print("```")
    for (n, p, t), cmd in commands.items():
        print(cmd)
    print("```")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
