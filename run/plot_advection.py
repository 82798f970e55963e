"""Plot and tables for run/bench_advection.sh (the advection work-precision study).

    /usr/bin/python3 run/plot_advection.py RESULTS.tsv OUT.png

The figure has four panels: forward error at T and gradient error (rows) for the smooth (gaussian)
and the discontinuous (square) profile (columns), each against the median wall time; one colour
per scheme, solid for RK4 (a dt/h = 0.5), dashed for Crank-Nicolson (a dt/h = 1), dotted for RK4
with a dt/h = 0.1, a marker per N. The markdown tables
(error, time, over/undershoot per scheme, integrator and N) go to stdout.
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLOURS = {"fd2": "tab:blue", "fd4": "tab:orange", "upwind": "tab:green", "spectral": "tab:red"}
STYLE = {"rk4": "-", "cn": "--", "rk4_small_dt": ":"}


def load(path):
    rows = []
    with open(path) as f:
        lines = [l for l in f if not l.startswith("#")]
    for r in csv.DictReader(lines, delimiter="\t"):
        for k in r:
            if k not in ("scheme", "profile", "integrator"):
                r[k] = float(r[k])
        rows.append(r)
    return rows


def main(tsv, png):
    rows = load(tsv)
    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    for col, profile in enumerate(("smooth", "square")):
        for row, (what, label) in enumerate((("forward", "relative L2 error of u(T)"), ("gradient", "relative error of dJ/da"))):
            ax = axes[row][col]
            for scheme in COLOURS:
                for integ in STYLE:
                    sel = sorted((r for r in rows if r["scheme"] == scheme and r["profile"] == profile and r["integrator"] == integ),
                                 key=lambda r: r["N"])
                    if not sel:
                        continue
                    x = [r[what + "_time"] for r in sel]
                    y = [max(r[what + "_error"], 1e-16) for r in sel]
                    ax.loglog(x, y, STYLE[integ], color=COLOURS[scheme], marker="o", ms=3, label=f"{scheme} {integ}")
                    ax.annotate(f"{int(sel[-1]['N'])}", (x[-1], y[-1]), fontsize=7, color=COLOURS[scheme])
            ax.set_title(f"{what}, {'gaussian (smooth)' if profile == 'smooth' else 'square pulse'}")
            ax.set_xlabel(f"median wall time of one {'forward solve' if what == 'forward' else 'gradient'} [s]")
            ax.set_ylabel(label)
            ax.grid(True, which="major", alpha=0.3)
    axes[0][0].legend(fontsize=8, ncol=2)
    fig.suptitle("Advection u_t + a u_x = 0 on [0, 2pi), a = 1.05, T = 2pi: error against wall time (labels: largest N)")
    fig.tight_layout()
    fig.savefig(png, dpi=110)

    for profile in ("smooth", "square"):
        print(f"\n### {'gaussian (width 0.8)' if profile == 'smooth' else 'square pulse (width 2)'}\n")
        print("| scheme | integrator | N | steps | forward error | forward time [s] median (min) | gradient error | gradient time [s] median (min) | overshoot | undershoot |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
        for scheme in COLOURS:
            for integ in STYLE:
                for r in sorted((r for r in rows if r["scheme"] == scheme and r["profile"] == profile and r["integrator"] == integ),
                                key=lambda r: r["N"]):
                    print(f"| {scheme} | {integ} | {int(r['N'])} | {int(r['steps'])} | {r['forward_error']:.2e} | "
                          f"{r['forward_time']:.2e} ({r['forward_time_min']:.2e}) | {r['gradient_error']:.2e} | "
                          f"{r['gradient_time']:.2e} ({r['gradient_time_min']:.2e}) | "
                          f"{r['overshoot']:.2e} | {r['undershoot']:.2e} |")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
