"""Tables and plot for run/bench_checkpoint.sh (medians over the repetitions it left in OUT).

    /usr/bin/python3 run/bench_checkpoint.py OUT [PLOT.png]

Definitions, per rank count and T (n steps):
  peak RSS         maximum resident set of the gradient run (GNU time, largest process)
  trajectory RSS   peak RSS of the gradient run - peak RSS of the forward-only run
  gradient time    wall(gradient run) - wall(forward run): one forward with trajectory + adjoint
  t(n, s)          binomial optimum r n - beta(s+1, r-1), beta(s, r) = C(s+r, s),
                   r = min{r : beta(s, r) >= n}; computed here independently of the C++ code
"""
import csv
import math
import statistics
import sys
from collections import defaultdict


def beta(s, r):
    return math.comb(s + r, s) if r >= 0 else 0


def optimum(n, s):
    if n <= 1:
        return 0
    r = 0
    while beta(s, r) < n:
        r += 1
    return r * n - beta(s + 1, r - 1), r


def order(config):
    return (-1, 0) if config == "forward" else (0, 0) if config == "full" else (1, int(config))


def main():
    out = sys.argv[1]
    png = sys.argv[2] if len(sys.argv) > 2 else None
    runs = defaultdict(list)
    info = {}
    with open(f"{out}/runs.tsv") as f:
        for row in csv.DictReader(f, delimiter="\t"):
            key = (int(row["nprocs"]), float(row["T"]), row["config"])
            runs[key].append((float(row["wall_s"]), int(row["rss_kb"])))
            info[key] = row
    med = {k: (statistics.median(w for w, _ in v), statistics.median(m for _, m in v), len(v)) for k, v in runs.items()}
    nprocs = sorted({k[0] for k in med})
    Ts = sorted({k[1] for k in med})
    configs = sorted({k[2] for k in med if k[2] != "forward"}, key=order)
    label = {c: "full storage" if c == "full" else f"budget {c}" for c in configs}

    for np_ in nprocs:
        steps = {T: int(info[(np_, T, "forward")]["steps"]) for T in Ts if (np_, T, "forward") in info}
        reps = max(v[2] for k, v in med.items() if k[0] == np_)
        print(f"\n### {np_} rank{'s' if np_ > 1 else ''} (medians of {reps} runs)\n")
        print("Peak resident set (MB) of the gradient run; in brackets the part above the forward-only run:\n")
        print("| steps n | forward only | " + " | ".join(label[c] for c in configs) + " |")
        print("|---:|---:|" + "---:|" * len(configs))
        for T in Ts:
            base = med[(np_, T, "forward")][1] / 1024
            cells = [f"{med[(np_, T, c)][1] / 1024:.1f} ({med[(np_, T, c)][1] / 1024 - base:+.1f})" for c in configs
                     if (np_, T, c) in med]
            print(f"| {steps[T]} | {base:.1f} | " + " | ".join(cells) + " |")
        print("\nTime of one gradient (s) = gradient run - forward run; in brackets relative to full storage:\n")
        print("| steps n | forward solve | " + " | ".join(label[c] for c in configs) + " |")
        print("|---:|---:|" + "---:|" * len(configs))
        for T in Ts:
            fwd = med[(np_, T, "forward")][0]
            full = med[(np_, T, "full")][0] - fwd if (np_, T, "full") in med else None
            cells = []
            for c in configs:
                g = med[(np_, T, c)][0] - fwd
                cells.append(f"{g:.2f}" + (f" ({g / full:.2f}x)" if full and c != "full" else ""))
            print(f"| {steps[T]} | {fwd:.2f} (whole run) | " + " | ".join(cells) + " |")
        print("\nRe-run forward steps during the adjoint against the binomial optimum t(n, s):\n")
        print("| steps n | storage | states held | r | t(n, s) (formula) | measured | measured / n |")
        print("|---:|---|---:|---:|---:|---:|---:|")
        for T in Ts:
            n = steps[T]
            for c in configs:
                row = info[(np_, T, c)]
                measured = int(row["recomputed"])
                if c == "full":
                    formula, r = n - 1, "-"
                else:
                    formula, r = optimum(n, int(c))
                    if int(row["optimum"]) != formula:
                        raise SystemExit(f"C++ optimum {row['optimum']} != formula {formula} for n={n}, s={c}")
                print(f"| {n} | {label[c]} | {row['stored']} | {r} | {formula} | {measured} | {measured / n:.2f} |")

    if png:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(1, 3, figsize=(16, 4.4))
        np_ = nprocs[0]
        n = [int(info[(np_, T, "forward")]["steps"]) for T in Ts]
        ax[0].plot(n, [med[(np_, T, "forward")][1] / 1024 for T in Ts], "k:", marker="x", label="forward only")
        for c in configs:
            rss = [med[(np_, T, c)][1] / 1024 for T in Ts]
            extra = [max(med[(np_, T, c)][1] - med[(np_, T, "forward")][1], 1) / 1024 for T in Ts]
            ax[0].plot(n, rss, marker="o", label=label[c])
            ax[1].plot(n, extra, marker="o", label=label[c])
            ax[2].plot(n, [med[(np_, T, c)][0] - med[(np_, T, "forward")][0] for T in Ts], marker="o", label=label[c])
        titles = ["Peak resident set of a gradient run", "Above the forward-only run (trajectory)",
                  "Time of one gradient (forward + adjoint)"]
        ylabels = ["peak resident set (MB)", "peak RSS - forward-only RSS (MB)", "gradient time (s)"]
        for a, t, y in zip(ax, titles, ylabels):
            a.set_xscale("log")
            a.set_yscale("log")
            a.set_xlabel("time steps n")
            a.set_ylabel(y)
            a.set_title(t)
        for a in ax:
            a.grid(True, which="both", alpha=0.3)
            a.legend()
        fig.suptitle(f"Binomial checkpointing, wave scene (2 x 1000 unknowns, RK4), {np_} rank{'s' if np_ > 1 else ''}")
        fig.tight_layout()
        fig.savefig(png, dpi=110)
        print(f"\nPlot: {png}")


if __name__ == "__main__":
    main()
