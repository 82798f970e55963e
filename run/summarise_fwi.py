#!/usr/bin/env python3
"""Summarise the main job's FWI results (HDF5 files in a results directory) as Markdown tables,
and plot the objective landscape J(c) of the seed scene if it was computed. The first table puts
the seed notebook's published figures beside flexipde's on the notebook scenes
(examples/scenes/notebook_fwi_*.opts), each with the command that produced it (the first line of
the case's log, "$ command").

Usage: /usr/bin/python3 run/summarise_fwi.py results > results/summary.md
       /usr/bin/python3 run/summarise_fwi.py --notebook results      (the notebook table alone)
"""
import os
import sys

import h5py
import numpy as np

SEED = {"Adam": 0.0170, "L-BFGS": 0.0142}

# The seed notebook's printed figures (JAX, float32 unless said) and its float64 loss and gradient norm.
NOTEBOOK = {
    "loss": "3.944904 (float32), 3.944720 (float64)",
    "gnorm": "4.976274 (float32), 4.976304 (float64)",
    "grange": "[-0.264329, -0.000011] (float32)",
    "closs": "15.758533 (float32)",
    "adam_c": "0.999937",
    "adam_rmse": "0.016962",
    "lbfgs_rmse": "0.014198",
}


def command(d, name):
    """The command of a case, from the first line of its log ("$ command"), as a user types it."""
    try:
        with open(os.path.join(d, name + ".log")) as f:
            first = f.readline().strip()
    except OSError:
        return ""
    if not first.startswith("$ "):
        return ""
    cmd = first[2:].replace("--allow-run-as-root ", "").replace("--oversubscribe ", "")
    return "`" + cmd + "`"


def history_end(path):
    with h5py.File(path, "r") as f:
        h = f["history"]
        its = int(np.asarray(h["iteration"]).ravel()[-1])
        rmse = float(np.asarray(h["rmse"]).ravel()[-1])
        rec = None
        if "scalars" in f and "wave_c_recovered" in f["scalars"]:
            rec = float(np.asarray(f["scalars/wave_c_recovered"]).ravel()[0])
    return its, rmse, rec


def notebook_table(d):
    """Markdown lines: the notebook's figures beside flexipde's (None if the cases were not run)."""
    p = lambda n: os.path.join(d, n + ".h5")
    if not os.path.exists(p("notebook_linear_gradient")):
        return None
    rows = []
    with h5py.File(p("notebook_linear_gradient"), "r") as f:
        J = float(np.asarray(f["gradient/J"]).ravel()[0])
        g = np.asarray(f["gradient/dJdp"]).ravel()
    cmd = command(d, "notebook_linear_gradient")
    rows.append(("linear case: initial loss J = norm of u(T) - d", NOTEBOOK["loss"], "%.6f" % J, cmd))
    rows.append(("linear case: gradient norm", NOTEBOOK["gnorm"], "%.6f" % np.linalg.norm(g), cmd))
    rows.append(("linear case: gradient range", NOTEBOOK["grange"], "[%.6f, %.6f]" % (g.min(), g.max()), cmd))
    if os.path.exists(p("notebook_constant_gradient")):
        with h5py.File(p("notebook_constant_gradient"), "r") as f:
            Jc = float(np.asarray(f["gradient/J"]).ravel()[0])
        rows.append(("constant case: initial loss (c = 0.8)", NOTEBOOK["closs"], "%.6f" % Jc,
                     command(d, "notebook_constant_gradient")))
    for name, label, key, what in [
        ("notebook_constant_adam", "constant case: Adam, lr 1e-3, 1000 iterations: final c", "adam_c", "c"),
        ("notebook_linear_adam", "linear case: Adam, lr 1e-3, 1000 iterations: velocity RMSE", "adam_rmse", "rmse"),
        ("notebook_linear_lmvm", "linear case: L-BFGS (LMVM), gradient tolerance 1e-5: velocity RMSE", "lbfgs_rmse",
         "rmse"),
        ("notebook_linear_lmvm_frtol", "linear case: L-BFGS (LMVM), gradient tolerance 1e-5 and relative decrease "
         "of J 1e-5 (scipy L-BFGS-B's tol): velocity RMSE", "lbfgs_rmse", "rmse"),
        ("notebook_linear_blmvm", "linear case, beyond the notebook: BLMVM, bounds [0.5, 2], Tikhonov 1e-2: "
         "velocity RMSE", None, "rmse"),
    ]:
        if not os.path.exists(p(name)):
            continue
        its, rmse, c = history_end(p(name))
        value = "%.7f" % c if what == "c" else "%.6f (%d iterations)" % (rmse, its)
        rows.append((label, NOTEBOOK[key] if key else "-", value, command(d, name)))
    lines = ["| quantity | notebook | flexipde (float64) | command |", "| --- | --- | --- | --- |"]
    lines += ["| %s | %s | %s | %s |" % r for r in rows]
    return lines


def row(path, label):
    with h5py.File(path, "r") as f:
        h = f["history"]
        rmse = np.asarray(h["rmse"]).ravel()
        mis = np.asarray(h["misfit"]).ravel()
        its = int(np.asarray(h["iteration"]).ravel()[-1]) if len(h["iteration"]) else 0
        rec = ""
        if "scalars" in f:
            for k in f["scalars"]:
                if k.endswith("_recovered"):
                    rec = "%s = %.8f" % (k[: -len("_recovered")], float(np.asarray(f["scalars"][k]).ravel()[0]))
        else:
            ct = np.asarray(f["fields/wave_c_true"]).ravel()
            cr = np.asarray(f["fields/wave_c_recovered"]).ravel()
            inner = slice(1, -1)
            rec = "max error %.4f; interior RMSE %.5f" % (
                np.abs(ct - cr).max(), np.sqrt(np.mean((ct[inner] - cr[inner]) ** 2)))
    return "| %s | %d | %.3e | %.3e | %.5f | %s |" % (label, its, mis[0], mis[-1], rmse[-1], rec)


def main():
    args = [a for a in sys.argv[1:] if a != "--notebook"]
    d = args[0] if args else "results"
    nb = notebook_table(d)
    if "--notebook" in sys.argv[1:]:
        print("\n".join(nb or ["(no notebook cases in %s)" % d]))
        return
    if nb:
        print("# The seed notebook's problem (examples/scenes/notebook_fwi_*.opts)\n")
        print("\n".join(nb))
        print("\nThe notebook ran in float32: its float64 loss and gradient norm are the ones to match. Adam's")
        print("RMSE after 1000 iterations on the linear case depends on round-off (a 1e-12 relative change of the")
        print("gradient moves it between 0.016 and 0.027, docs/fwi.md).\n")
    cases = [
        ("fwi_constant_from_0.8.h5", "1a constant c, BLMVM from 0.8"),
        ("fwi_constant.h5", "1b constant c, 151-point scan + BLMVM"),
        ("fwi_linear_blmvm.h5", "2 linear c(x), BLMVM, bounds [0.5,2]"),
        ("fwi_linear_lmvm.h5", "2 linear c(x), LMVM"),
        ("fwi_receivers_blmvm.h5", "3 linear c(x) from traces: 3 shots, 21 receivers, BLMVM"),
    ]
    print("# Seed FWI results: flexipde beyond the notebook (written by run/main.sh)\n")
    print("| case | iterations | initial misfit | final misfit | parameter RMSE | recovered |")
    print("| --- | --- | --- | --- | --- | --- |")
    for fn, label in cases:
        p = os.path.join(d, fn)
        if os.path.exists(p):
            print(row(p, label))
    print("\nSeed's published RMSE for case 2: Adam %.4f, L-BFGS %.4f." % (SEED["Adam"], SEED["L-BFGS"]))
    print("The two wall values of c(x) do not enter the equations (u = 0 there): only the smoothness term")
    print("moves them, so 'interior RMSE' also reports the error without them.")
    land = os.path.join(d, "fwi_landscape.h5")
    if os.path.exists(land):
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        with h5py.File(land, "r") as f:
            c = np.asarray(f["landscape/parameter"]).ravel()
            J = np.asarray(f["landscape/objective"]).ravel()
        fig, ax = plt.subplots(figsize=(6, 3.5))
        ax.semilogy(c, np.maximum(J, 1e-12), "-o", ms=2)
        ax.set_xlabel("c")
        ax.set_ylabel("J(c) = 0.5||u(T) - d||^2")
        ax.set_title("Seed scene: objective landscape (data from c = 1)")
        ax.grid(True, which="both", alpha=0.3)
        fig.tight_layout()
        fig.savefig(os.path.join(d, "fwi_landscape.png"), dpi=120)
        mins = [i for i in range(1, len(J) - 1) if J[i] <= J[i - 1] and J[i] <= J[i + 1]]
        print("\nObjective landscape (results/fwi_landscape.png): local minima of J(c) on the scan at c = "
              + ", ".join("%.3f (J = %.2e)" % (c[i], J[i]) for i in mins) + ".")
    for name, title in (("fwi_2d", "Case 4, 2D"), ("fwi_marmousi", "Case 5, Marmousi-like section"), ("fwi_3d", "Case 6, 3D")):
        log = os.path.join(d, name + ".log")
        if os.path.exists(log):
            with open(log) as f:
                lines = [l.strip() for l in f if l.startswith(name + ":") or l.startswith("recovered RMSE")]
            print("\n%s (results/%s_*.png): " % (title, name) + " ".join(lines))


if __name__ == "__main__":
    main()
