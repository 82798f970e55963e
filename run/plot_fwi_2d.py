"""Images of the 2D FWI demo (examples/fwi_2d.cpp): true / initial / recovered c(x, y) with the
sources and receivers, and the misfit and velocity-RMSE history.

    /usr/bin/python3 run/plot_fwi_2d.py results/fwi_2d.h5 docs/fwi_2d
writes docs/fwi_2d_models.png and docs/fwi_2d_history.png and prints the RMSE over the whole grid
and over the region inside the sponge (0.15 <= x, y <= 0.85).
"""
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def main(path, prefix):
    f = h5py.File(path, "r")
    x = np.asarray(f["grid/x"]).reshape(-1)
    y = np.asarray(f["grid/y"]).reshape(-1)
    fields = {k: np.asarray(f["fields/wave2d_c_" + k]) for k in ("true", "initial", "recovered")}
    ny, nx = fields["true"].shape if fields["true"].ndim == 2 else (int(round(np.sqrt(x.size))),) * 2
    for k in fields:
        fields[k] = fields[k].reshape(ny, nx)
    xs, ys = x.reshape(ny, nx)[0, :], y.reshape(ny, nx)[:, 0]
    inner = np.ix_((ys >= 0.15) & (ys <= 0.85), (xs >= 0.15) & (xs <= 0.85))
    for k in ("initial", "recovered"):
        e = fields[k] - fields["true"]
        print("%-9s RMSE %.4e (whole grid), %.4e (inside the sponge)" % (k, np.sqrt(np.mean(e**2)), np.sqrt(np.mean(e[inner] ** 2))))
    rx, ry = np.asarray(f["survey/receivers_x"]), np.asarray(f["survey/receivers_y"])
    vmin, vmax = fields["true"].min(), fields["true"].max()
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2), constrained_layout=True)
    for ax, k in zip(axes, ("true", "initial", "recovered")):
        im = ax.imshow(fields[k], origin="upper", extent=[xs[0], xs[-1], ys[-1], ys[0]], vmin=vmin, vmax=vmax, cmap="viridis")
        ax.plot(rx, ry, "v", color="w", ms=3, label="receivers")
        ax.plot([0.2, 0.4, 0.6, 0.8], [0.2] * 4, "*", color="r", ms=9, label="sources")
        ax.add_patch(plt.Rectangle((0.15, 0.15), 0.7, 0.7, fill=False, ls="--", color="k", lw=0.8))
        ax.set_title("c %s" % k)
        ax.set_xlabel("x")
        ax.set_ylabel("depth y")
    axes[0].legend(loc="lower left", fontsize=7)
    fig.colorbar(im, ax=axes, shrink=0.8, label="c")
    fig.savefig(prefix + "_models.png", dpi=110)
    it = np.asarray(f["history/iteration"])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 3.6), constrained_layout=True)
    a1.semilogy(it, np.asarray(f["history/misfit"]), "o-", ms=3, label="misfit J")
    a1.semilogy(it, np.asarray(f["history/objective"]), "-", label="J + TV")
    a1.set_xlabel("iteration")
    a1.legend()
    a2.plot(it, np.asarray(f["history/rmse"]), "o-", ms=3)
    a2.set_xlabel("iteration")
    a2.set_ylabel("velocity RMSE (whole grid)")
    fig.savefig(prefix + "_history.png", dpi=110)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else "docs/fwi_2d")
