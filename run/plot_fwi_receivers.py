"""The 1D receiver FWI runs of run/fwi_receivers.sh: recovered c(x) and |c - c_true| for BLMVM, LMVM
and Adam with receivers along the domain and at both ends, and the RMSE history.

    /usr/bin/python3 run/plot_fwi_receivers.py results/fwi_receivers docs/fwi_receivers_1d.png
"""
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def main(folder, out):
    fig, axes = plt.subplots(1, 3, figsize=(14, 3.8), constrained_layout=True)
    for rec, ls in (("spread", "-"), ("ends", ":")):
        for method, color in (("blmvm", "C0"), ("lmvm", "C1"), ("adam", "C2")):
            f = h5py.File("%s/%s_%s.h5" % (folder, rec, method), "r")
            x = np.asarray(f["grid/x"]).ravel()
            t = np.asarray(f["fields/wave_c_true"]).ravel()
            r = np.asarray(f["fields/wave_c_recovered"]).ravel()
            label = "%s, %s" % (method, rec)
            if rec == "spread" and method == "blmvm":
                axes[0].plot(x, t, "k-", lw=3, alpha=0.3, label="true")
                axes[0].plot(x, np.asarray(f["fields/wave_c_initial"]).ravel(), "k--", lw=1, label="initial")
            axes[0].plot(x, r, ls, color=color, lw=1, label=label)
            axes[1].semilogy(x, np.abs(r - t) + 1e-12, ls, color=color, lw=1, label=label)
            axes[2].semilogy(np.asarray(f["history/iteration"]), np.asarray(f["history/rmse"]), ls, color=color, label=label)
    axes[0].set_title("c(x)")
    axes[1].set_title("|c - c_true|")
    axes[2].set_title("velocity RMSE per iteration")
    axes[2].axhline(1e-3, color="gray", lw=0.8)
    for a in axes:
        a.legend(fontsize=7)
    axes[2].set_xlabel("iteration")
    axes[0].set_xlabel("x")
    axes[1].set_xlabel("x")
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else "docs/fwi_receivers_1d.png")
