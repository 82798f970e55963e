#!/bin/sh
''''exec "${PYTHON:-/usr/bin/python3}" "$0" "$@" # '''
# The two lines above re-run this file with $PYTHON (default /usr/bin/python3, Debian's, with
# numpy, matplotlib and h5py); to Python they are only a string.
"""Plot the results of `flexipde -task invert -output F.h5`.

    PYTHON=/usr/bin/python3 run/plot_fwi.py results/fwi_linear.h5 [more.h5 ...] [-o DIR]

For each results file F.h5 it writes, next to the file (or into DIR):

  F_params.png   true / initial / recovered c(x) for every field parameter (/fields/<p>_true ...);
                 scalar parameters (/scalars/<p>_*) are printed and shown in the history title
  F_history.png  objective and misfit (log scale), gradient norm and parameter RMSE per iteration
  F_state.png    the observed component of U(T) at the recovered parameters against the data,
                 and their difference (component 0, u, unless --component N: the file does not
                 record the run's -objective_component)

File layout (include/flexipde/io.hpp): /grid/x; /fields/<p>_true|initial|recovered, /fields/U_final
(n x dof, interleaved components), /fields/data (n); /scalars/<p>_true|initial|recovered (length 1);
/history/{iteration,objective,misfit,gradient_norm,rmse}.
"""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import h5py  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

SUFFIXES = ("true", "initial", "recovered")
STYLE = {
    "true": dict(color="k", lw=2.0, ls="-"),
    "initial": dict(color="tab:blue", lw=1.5, ls="--"),
    "recovered": dict(color="tab:red", lw=1.5, ls="-"),
}
COMPONENT_NAMES = {0: "u", 1: "v"}  # the wave model's components; others are shown by index


def read(path):
    """Everything the plots need, as numpy arrays, from one results file."""
    r = {"path": path, "fields": {}, "scalars": {}, "history": {}}
    with h5py.File(path, "r") as f:
        r["x"] = np.asarray(f["grid/x"][...]).ravel() if "grid/x" in f else None
        for group, kind in (("fields", "fields"), ("scalars", "scalars")):
            if group not in f:
                continue
            for name, ds in f[group].items():
                for s in SUFFIXES:
                    if name.endswith("_" + s):
                        r[kind].setdefault(name[: -len(s) - 1], {})[s] = np.asarray(ds[...])
        r["U_final"] = np.asarray(f["fields/U_final"][...]) if "fields/U_final" in f else None
        r["data"] = np.asarray(f["fields/data"][...]).ravel() if "fields/data" in f else None
        if "history" in f:
            for name, ds in f["history"].items():
                r["history"][name] = np.asarray(ds[...]).ravel()
    n = r["x"].size if r["x"] is not None else None
    if r["x"] is None:  # fall back to grid indices
        for v in r["fields"].values():
            n = next(iter(v.values())).size
            break
        r["x"] = np.arange(n if n else 0, dtype=float)
    return r


def state_components(U, n):
    """U(T) as an (n, dof) array (PETSc writes a DMDA vector with dof > 1 as n x dof)."""
    U = np.asarray(U)
    if U.ndim == 1:
        return U.reshape(n, -1) if n and U.size % n == 0 else U[:, None]
    return U.reshape(U.shape[0], -1)


def observed_component(U, data, requested, path):
    """Index of U's column that the data describe: as requested, else 0 (the driver's default
    -objective_component; the file does not record it), with a hint when another fits far better."""
    if requested is not None:
        if not 0 <= requested < U.shape[1]:
            sys.exit(f"plot_fwi: --component {requested} but U(T) has {U.shape[1]} component(s)")
        return requested
    res = [np.linalg.norm(U[:, k] - data) for k in range(U.shape[1])]
    best = int(np.argmin(res))
    if best != 0 and res[best] < 0.1 * res[0]:
        print(f"plot_fwi: {path}: the data match component {best} of U(T) much better than component 0; "
              f"if the run used -objective_component, pass --component {best}", file=sys.stderr)
    return 0


def positive(y):
    y = np.asarray(y, dtype=float)
    return np.where(y > 0, y, np.nan)  # log axes: hide zeros rather than fail


def plot_params(r, out):
    if not r["fields"]:
        return None
    names = sorted(r["fields"])
    fig, axes = plt.subplots(len(names), 1, figsize=(8, 3.6 * len(names)), squeeze=False)
    for ax, name in zip(axes[:, 0], names):
        vals = r["fields"][name]
        for s in SUFFIXES:
            if s in vals:
                y = np.asarray(vals[s]).ravel()
                x = r["x"] if r["x"].size == y.size else np.arange(y.size)
                ax.plot(x, y, label=s, **STYLE[s])
        if "true" in vals and "recovered" in vals:
            e = np.sqrt(np.mean((vals["recovered"].ravel() - vals["true"].ravel()) ** 2))
            e0 = np.sqrt(np.mean((vals["initial"].ravel() - vals["true"].ravel()) ** 2)) if "initial" in vals else np.nan
            ax.set_title(f"{name}(x): RMSE to true {e0:.3e} (initial) -> {e:.3e} (recovered)")
        else:
            ax.set_title(f"{name}(x)")
        ax.set_xlabel("x")
        ax.set_ylabel(name)
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle(os.path.basename(r["path"]))
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def scalar_summary(r):
    parts = []
    for name in sorted(r["scalars"]):
        v = {s: float(np.asarray(a).ravel()[0]) for s, a in r["scalars"][name].items()}
        parts.append(name + ": " + ", ".join(f"{s} {v[s]:.6g}" for s in SUFFIXES if s in v))
    return "; ".join(parts)


def plot_history(r, out):
    h = r["history"]
    if not h:
        return None
    n = max(a.size for a in h.values())
    it = h.get("iteration", np.arange(n, dtype=float))
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    ax = axes[0]
    if "objective" in h:
        ax.semilogy(it, positive(h["objective"]), color="k", lw=1.8, label="objective")
    if "misfit" in h:
        ax.semilogy(it, positive(h["misfit"]), color="tab:orange", lw=1.2, ls="--", label="misfit")
    ax.set_title("loss")
    ax.legend()
    ax = axes[1]
    if "gradient_norm" in h:
        ax.semilogy(it, positive(h["gradient_norm"]), color="tab:green")
    ax.set_title("gradient norm")
    ax = axes[2]
    if "rmse" in h:
        e = positive(h["rmse"])
        ax.plot(it, e, color="tab:red")
        fin = e[np.isfinite(e)]
        if fin.size and fin.max() > 10 * fin.min():  # log only when it spans a decade
            ax.set_yscale("log")
    ax.set_title("parameter RMSE to the true values")
    for ax in axes:
        ax.set_xlabel("iteration")
        ax.grid(alpha=0.3)
        if it.size and it[-1] > 0:
            ax.set_xlim(it[0], it[-1])
    title = f"{os.path.basename(r['path'])}: {it.size} iterates"
    if "objective" in h and h["objective"].size:
        title += f", objective {h['objective'][0]:.3e} -> {h['objective'][-1]:.3e}"
    s = scalar_summary(r)
    if s:
        title += "\n" + s
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def plot_state(r, out, component):
    if r["U_final"] is None or r["data"] is None:
        return None
    data = r["data"]
    U = state_components(r["U_final"], data.size)
    if U.shape[0] != data.size:
        print(f"plot_fwi: {r['path']}: U_final has {U.shape[0]} points, data {data.size}; no state plot",
              file=sys.stderr)
        return None
    k = observed_component(U, data, component, r["path"])
    cname = COMPONENT_NAMES.get(k, f"component {k}") if U.shape[1] > 1 else "u"
    x = r["x"] if r["x"].size == data.size else np.arange(data.size)
    fig, (a0, a1) = plt.subplots(2, 1, figsize=(8, 6), sharex=True, gridspec_kw=dict(height_ratios=[2, 1]))
    a0.plot(x, data, color="k", lw=2.0, label="data (true parameters)")
    a0.plot(x, U[:, k], color="tab:red", lw=1.2, ls="--", label=f"{cname}(T), recovered parameters")
    a0.set_ylabel(f"{cname}(x, T)")
    a0.legend()
    a0.grid(alpha=0.3)
    res = U[:, k] - data
    rel = np.linalg.norm(res) / max(np.linalg.norm(data), np.finfo(float).tiny)
    a0.set_title(f"{os.path.basename(r['path'])}: final state vs data, relative residual {rel:.3e}")
    a1.plot(x, res, color="tab:purple", lw=1.0)
    a1.set_ylabel("residual")
    a1.set_xlabel("x")
    a1.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(
        description="Plot flexipde inversion results (-task invert -output F.h5): parameters, history, final state.")
    ap.add_argument("files", nargs="+", metavar="F.h5")
    ap.add_argument("-o", "--outdir", help="write the PNGs here instead of next to each file")
    ap.add_argument("--component", type=int, default=None,
                    help="column of U_final that the data describe, as the run's -objective_component "
                         "(default 0: u for the wave model)")
    a = ap.parse_args(argv)
    if a.outdir:
        os.makedirs(a.outdir, exist_ok=True)
    stems = {}
    for path in a.files:
        stem = os.path.splitext(os.path.basename(path))[0]
        if a.outdir and stem in stems and stems[stem] != os.path.abspath(path):
            # two inputs with the same name in one output directory: keep both
            stem = os.path.basename(os.path.dirname(os.path.abspath(path))) + "_" + stem
        stems[stem] = os.path.abspath(path)
        base = os.path.join(a.outdir if a.outdir else os.path.dirname(os.path.abspath(path)), stem)
        try:
            r = read(path)
        except (OSError, KeyError) as e:
            sys.exit(f"plot_fwi: cannot read {path}: {e}")
        written = [plot_params(r, base + "_params.png"), plot_history(r, base + "_history.png"),
                   plot_state(r, base + "_state.png", a.component)]
        s = scalar_summary(r)
        if s:
            print(f"{path}: {s}")
        for w in written:
            if w:
                print(w)
        if not any(written):
            print(f"plot_fwi: {path}: no inversion results in it (no /fields, /history or /fields/data)",
                  file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
