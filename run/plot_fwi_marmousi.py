"""Images of the Marmousi-like inversion (examples/fwi_marmousi.cpp): true / initial / recovered c(x, y)
and the misfit and velocity-RMSE history through the frequency bands.

    /usr/bin/python3 run/plot_fwi_marmousi.py results/fwi_marmousi.h5 docs/fwi_marmousi
writes docs/fwi_marmousi_models.png and docs/fwi_marmousi_history.png and prints the velocity RMSE of
the initial and recovered models over the whole grid and away from the layer (0.15 from every edge).
"""
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from fwi_history import plot_history


def main(path, prefix):
    f = h5py.File(path, "r")
    x = np.asarray(f["grid/x"]).reshape(-1)
    y = np.asarray(f["grid/y"]).reshape(-1)
    fields = {k: np.asarray(f["fields/wave2d_c_" + k]).reshape(-1) for k in ("true", "initial", "recovered")}
    nx = int(np.sum(np.isclose(y, y[0])))
    ny = x.size // nx
    for k in fields:
        fields[k] = fields[k].reshape(ny, nx)
    xs, ys = x.reshape(ny, nx)[0, :], y.reshape(ny, nx)[:, 0]
    inner = np.ix_((ys >= 0.15) & (ys <= ys[-1] - 0.15), (xs >= 0.15) & (xs <= xs[-1] - 0.15))
    for k in ("initial", "recovered"):
        e = fields[k] - fields["true"]
        print("%-9s RMSE %.4e (whole grid), %.4e (away from the layer)" % (k, np.sqrt(np.mean(e**2)), np.sqrt(np.mean(e[inner] ** 2))))
    vmin, vmax = fields["true"].min(), fields["true"].max()
    fig, axes = plt.subplots(3, 1, figsize=(9, 9.5), constrained_layout=True)
    for ax, k in zip(axes, ("true", "initial", "recovered")):
        im = ax.imshow(fields[k], origin="upper", extent=[xs[0], xs[-1], ys[-1], ys[0]], vmin=vmin, vmax=vmax, cmap="jet",
                       aspect="equal")
        ax.set_title("c %s (km/s)" % k)
        ax.set_ylabel("depth (km)")
    axes[-1].set_xlabel("x (km)")
    fig.colorbar(im, ax=axes, shrink=0.6, label="c (km/s)")
    fig.savefig(prefix + "_models.png", dpi=100)
    plot_history(f, prefix + "_history.png", "BLMVM iteration (bands one after another)")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2] if len(sys.argv) > 2 else "docs/fwi_marmousi")
