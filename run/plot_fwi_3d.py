"""Images of the 3D inversion (examples/fwi_3d.cpp): slices of the true / initial / recovered c(x, y, z)
through the high-velocity body (a horizontal slice at its depth, vertical slices along x and along y
through its centre) and the misfit and velocity-RMSE history through the frequency bands.

    /usr/bin/python3 run/plot_fwi_3d.py results/fwi_3d.h5 docs/fwi_3d [x y z]
writes docs/fwi_3d_models.png and docs/fwi_3d_history.png (x y z: where the slices cut, default the
example's body centre 0.70 0.55 0.32) and prints the velocity RMSE of the initial and recovered models
over the whole grid, away from the sponge (-wave3d_sponge_width, default 0.12, from every face) and
inside the body, and the whole-band misfit before and after.
"""
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from fwi_history import plot_history

KINDS = ("true", "initial", "recovered")


def axis(values):
    """The distinct coordinates of one direction, in order."""
    return np.unique(np.round(values, 12))


def main(path, prefix, centre=(0.70, 0.55, 0.32), sponge=0.12):
    f = h5py.File(path, "r")
    xs, ys, zs = (axis(np.asarray(f["grid/" + d]).reshape(-1)) for d in "xyz")
    shape = (zs.size, ys.size, xs.size)  # PETSc writes a 3D DMDA Vec with x fastest
    c = {k: np.asarray(f["fields/wave3d_c_" + k]).reshape(shape) for k in KINDS}
    inner = np.ix_((zs >= sponge - 1e-9) & (zs <= zs[-1] - sponge + 1e-9), (ys >= sponge - 1e-9) & (ys <= ys[-1] - sponge + 1e-9),
                   (xs >= sponge - 1e-9) & (xs <= xs[-1] - sponge + 1e-9))
    body = c["true"] > c["true"][-1].max() + 1e-9  # faster than the deepest layer: the body
    for k in ("initial", "recovered"):
        e = c[k] - c["true"]
        print("%-9s RMSE %.4f (whole grid), %.4f (away from the sponge), %.4f (in the body); mean c in the body %.3f (true %.3f)"
              % (k, np.sqrt(np.mean(e**2)), np.sqrt(np.mean(e[inner] ** 2)), np.sqrt(np.mean(e[body] ** 2)),
                 c[k][body].mean(), c["true"][body].mean()))
    if "summary/misfit" in f:
        m = np.asarray(f["summary/misfit"])
        print("misfit of the whole band %.4e -> %.4e (reduced %.0f times)" % (m[0], m[1], m[0] / m[1]))

    ix, iy, iz = (int(np.argmin(abs(a - v))) for a, v in zip((xs, ys, zs), centre))
    survey = {k: np.asarray(f["survey/" + k]) for k in ("sources_x", "sources_y", "receivers_x", "receivers_y") if "survey/" + k in f}
    vmin, vmax = c["true"].min(), c["true"].max()
    fig, axes = plt.subplots(3, 3, figsize=(12, 8.6), constrained_layout=True)
    for row, k in enumerate(KINDS):
        a = axes[row, 0]  # horizontal slice through the body
        im = a.imshow(c[k][iz], origin="lower", extent=[xs[0], xs[-1], ys[0], ys[-1]], vmin=vmin, vmax=vmax, cmap="jet")
        if row == 0 and "receivers_x" in survey:
            a.plot(survey["receivers_x"], survey["receivers_y"], "k.", ms=1.5)
        if row == 0 and "sources_x" in survey:
            a.plot(survey["sources_x"], survey["sources_y"], "w*", ms=9, mec="k")
        a.set_title("c %s, depth z = %.2f km" % (k, zs[iz]))
        a.set_xlabel("x (km)")
        a.set_ylabel("y (km)")
        a = axes[row, 1]  # vertical slice along x
        a.imshow(c[k][:, iy, :], origin="upper", extent=[xs[0], xs[-1], zs[-1], zs[0]], vmin=vmin, vmax=vmax, cmap="jet")
        a.set_title("c %s, y = %.2f km" % (k, ys[iy]))
        a.set_xlabel("x (km)")
        a.set_ylabel("depth z (km)")
        a = axes[row, 2]  # vertical slice along y
        a.imshow(c[k][:, :, ix], origin="upper", extent=[ys[0], ys[-1], zs[-1], zs[0]], vmin=vmin, vmax=vmax, cmap="jet")
        a.set_title("c %s, x = %.2f km" % (k, xs[ix]))
        a.set_xlabel("y (km)")
        a.set_ylabel("depth z (km)")
    fig.colorbar(im, ax=axes, shrink=0.6, label="c (km/s)")
    fig.savefig(prefix + "_models.png", dpi=90)

    plot_history(f, prefix + "_history.png")


if __name__ == "__main__":
    args = sys.argv[1:]
    centre = tuple(float(v) for v in args[2:5]) if len(args) >= 5 else (0.70, 0.55, 0.32)
    main(args[0], args[1] if len(args) > 1 else "docs/fwi_3d", centre)
