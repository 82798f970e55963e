#!/usr/bin/env python3
"""Plots of the learned Burgers discretisation (docs/learned_discretisation.md).

  run/plot_learned.py TRAIN_STENCIL.h5 TRAIN_NETWORK.h5 EVAL_STENCIL.h5 EVAL_NETWORK.h5 OUTDIR

TRAIN_*: learned_burgers_train -output files; EVAL_*: learned_burgers_evaluate -output files (with
the stencil's and the network's weights). Writes learned_training.png, learned_snapshots.png,
learned_error_time.png and learned_work_precision.png into OUTDIR and prints, for each classical
scheme, the grid and the solve time at which it reaches each learned scheme's error.
"""
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

CLASSICAL = [("eo", "Engquist-Osher (1st order)"), ("centred", "centred"),
             ("upwind2", "2nd-order upwind"), ("kappa3", "3rd-order upwind-biased (untrained start)")]


def series(f, path):
    return np.asarray(f[path][:]).ravel()


def crossing(cells, err, secs, target):
    """Grid and time (log-log interpolation) at which err(cells) falls to target; None beyond the range."""
    le, lc, ls = np.log(err), np.log(cells), np.log(secs)
    for k in range(len(cells) - 1):
        if err[k] >= target >= err[k + 1]:
            s = (np.log(target) - le[k]) / (le[k + 1] - le[k])
            return np.exp(lc[k] + s * (lc[k + 1] - lc[k])), np.exp(ls[k] + s * (ls[k + 1] - ls[k]))
    return None


def main(argv):
    if len(argv) != 6:
        sys.exit(__doc__)
    tr_s, tr_n, ev_s, ev_n, out = h5py.File(argv[1]), h5py.File(argv[2]), h5py.File(argv[3]), h5py.File(argv[4]), argv[5]

    # training history
    fig, ax = plt.subplots(figsize=(6, 4))
    n_theta = len(series(tr_n, "vectors/learned_burgers_theta"))
    for f, lab in ((tr_s, "one stencil (3 weights)"), (tr_n, "network (%d weights)" % n_theta)):
        ax.semilogy(series(f, "history/iteration"), series(f, "history/rmse"), "o-", ms=3, label=lab)
    ax.set_xlabel("TAO iteration")
    ax.set_ylabel("space-time RMS error on the training starts")
    ax.set_title("Training: sqrt(2 J)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out + "/learned_training.png", dpi=120)

    # snapshots on the training grid, first held-out start
    settings = series(ev_n, "settings/values")
    n = int(settings[0])
    t = series(ev_n, "snapshots/time")
    x = (np.arange(n) + 0.5) / n
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), sharey=True)
    for ax, tt in zip(axes, (0.1, 0.2, 0.5)):
        k = int(np.argmin(abs(t - tt)))
        ref = series(ev_n, "snapshots/reference").reshape(len(t), n)[k]
        ax.step(np.r_[0, (np.arange(n) + 1) / n], np.r_[ref[0], ref], "k-", where="pre", lw=1, label="reference (cell averages)")
        for name, lab in CLASSICAL[:1] + CLASSICAL[3:]:
            ax.plot(x, series(ev_n, "snapshots/" + name).reshape(len(t), n)[k], ".--", lw=1, label=lab)
        ax.plot(x, series(ev_s, "snapshots/learned").reshape(len(t), n)[k], "s-", ms=4, lw=1.5, label="learned stencil")
        ax.plot(x, series(ev_n, "snapshots/learned").reshape(len(t), n)[k], "o-", ms=4, lw=1.5, label="learned network")
        ax.set_title("t = %.2f (%d cells)" % (t[k], n))
        ax.set_xlabel("x")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("u")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out + "/learned_snapshots.png", dpi=120)

    # error over time
    fig, ax = plt.subplots(figsize=(6.5, 4))
    te = series(ev_n, "error/time")
    ax.semilogy(te[1:], series(ev_n, "error/learned")[1:], "o-", ms=3, label="learned network")
    ax.semilogy(te[1:], series(ev_s, "error/learned")[1:], "s-", ms=3, label="learned stencil")
    for name, lab in CLASSICAL:
        ax.semilogy(te[1:], series(ev_n, "error/" + name)[1:], "--", label=lab)
    T_train = series(tr_n, "train/settings")[2]
    ax.axvline(T_train, color="gray", lw=0.8)
    ax.text(T_train, ax.get_ylim()[1], " training horizon", va="top", fontsize=8, color="gray")
    ax.set_xlabel("t")
    ax.set_ylabel("L2 error against the reference")
    ax.set_title("Held-out starts, %d cells" % n)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out + "/learned_error_time.png", dpi=120)

    # work-precision
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for name, lab in CLASSICAL:
        c, e, s = (series(ev_n, "work_precision/%s_%s" % (name, q)) for q in ("cells", "error", "seconds"))
        ax.loglog(s, e, "o--", label=lab)
        for ci, ei, si in zip(c, e, s):
            ax.annotate("%d" % ci, (si, ei), fontsize=7, textcoords="offset points", xytext=(3, 3))
    for f, mk, lab in ((ev_n, "*", "learned network"), (ev_s, "P", "learned stencil")):
        ax.loglog(series(f, "work_precision/learned_seconds"), series(f, "work_precision/learned_error"), mk, ms=12,
                  label=lab + " (%d cells)" % n)
    ax.set_xlabel("wall time of one solve [s] (one core)")
    ax.set_ylabel("space-time RMS error")
    ax.set_title("Work-precision on held-out starts (labels: cells)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out + "/learned_work_precision.png", dpi=120)

    # where a classical scheme matches the learned error
    print("| learned scheme | its error | its solve [s] | classical | cells for the same error | solve there [s] |")
    print("| --- | --- | --- | --- | --- | --- |")
    for f, lab in ((ev_s, "stencil"), (ev_n, "network")):
        el, sl = series(f, "work_precision/learned_error")[0], series(f, "work_precision/learned_seconds")[0]
        for name, _ in CLASSICAL:
            c, e, s = (series(ev_n, "work_precision/%s_%s" % (name, q)) for q in ("cells", "error", "seconds"))
            hit = crossing(c, e, s, el)
            where = ("%.0f" % hit[0], "%.4f" % hit[1]) if hit else ("beyond %d" % c[-1], "-")
            print("| %s | %.2e | %.4f | %s | %s | %s |" % (lab, el, sl, name, where[0], where[1]))


if __name__ == "__main__":
    main(sys.argv)
