#!/usr/bin/env python3
"""Summarise the main job's FWI results (HDF5 files in a results directory) as a Markdown table,
and plot the objective landscape J(c) of the seed scene if it was computed.

Usage: /usr/bin/python3 run/summarise_fwi.py results > results/summary.md
"""
import os
import sys

import h5py
import numpy as np

SEED = {"Adam": 0.0170, "L-BFGS": 0.0142}


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
    d = sys.argv[1] if len(sys.argv) > 1 else "results"
    cases = [
        ("fwi_constant_from_0.8.h5", "1a constant c, BLMVM from 0.8"),
        ("fwi_constant.h5", "1b constant c, 151-point scan + BLMVM"),
        ("fwi_linear_blmvm.h5", "2 linear c(x), BLMVM, bounds [0.5,2]"),
        ("fwi_linear_lmvm.h5", "2 linear c(x), LMVM"),
        ("fwi_receivers_blmvm.h5", "3 linear c(x) from traces: 3 shots, 21 receivers, BLMVM"),
    ]
    print("# Seed FWI results (written by run/main.sh)\n")
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
    log2d = os.path.join(d, "fwi_2d.log")
    if os.path.exists(log2d):
        with open(log2d) as f:
            lines = [l.strip() for l in f if l.startswith("fwi_2d:") or l.startswith("recovered RMSE")]
        print("\nCase 4, 2D (results/fwi_2d_*.png): " + " ".join(lines))


if __name__ == "__main__":
    main()
