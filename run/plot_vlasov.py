#!/usr/bin/python3
"""Figures and tables of docs/vlasov.md: Landau damping, two-stream growth against the dispersion
relation, the nonlinear two-stream run (phase-space hole) and its invariants.

    /usr/bin/python3 run/plot_vlasov.py [--build build] [--out docs] [--np 2]

Runs build/vlasov_phase_space (mpiexec -n NP) for every case, writes docs/vlasov_*.png and prints
the markdown tables on stdout. The dispersion relation of a sum of Maxwellians,
    1 + sum_s n_s / (k^2 vt_s^2) [1 + zeta_s Z(zeta_s)] = 0,  zeta_s = (omega/k - u_s) / (sqrt(2) vt_s),
is solved by Newton's method with Z from scipy's Faddeeva function.
"""
import argparse
import os
import re
import subprocess
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.special import wofz


def Z(z):
    return 1j * np.sqrt(np.pi) * wofz(z)


def dielectric(w, k, beams):
    s = 1.0 + 0j
    for n, u, vt in beams:
        zeta = (w / k - u) / (np.sqrt(2) * vt)
        s += n / (k * k * vt * vt) * (1 + zeta * Z(zeta))
    return s


def root(w, k, beams):
    for _ in range(100):
        d = (dielectric(w + 1e-7, k, beams) - dielectric(w - 1e-7, k, beams)) / 2e-7
        step = dielectric(w, k, beams) / d
        w -= step
        if abs(step) < 1e-14:
            break
    return w


def two_stream_beams(r, v0=2.4, vt=1.0):
    return [(0.5, v0, vt), (0.5, -v0, vt * np.sqrt(r))]


class Runner:
    def __init__(self, build, np_, work):
        self.exe = os.path.join(build, "vlasov_phase_space")
        self.mpi = ["mpiexec", "-n", str(np_)]
        if os.geteuid() == 0:
            self.mpi[1:1] = ["--allow-run-as-root", "--oversubscribe"]
        self.work = work

    def run(self, name, *opts):
        hist = os.path.join(self.work, name + ".txt")
        cmd = self.mpi + [self.exe, "-history_file", hist, "-snapshot_prefix", os.path.join(self.work, name)] + list(opts)
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        return out, np.loadtxt(hist)


def snapshot(path, nx, nv):
    return np.fromfile(path, dtype=">f8", offset=8).reshape(nv, nx)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--build", default="build")
    ap.add_argument("--out", default="docs")
    ap.add_argument("--np", type=int, default=2)
    a = ap.parse_args()
    work = tempfile.mkdtemp(prefix="vlasov_docs.")
    R = Runner(a.build, a.np, work)

    # 1. Landau damping: convergence of the fitted rate and frequency (and the effect of the
    #    optional dissipation on one grid).
    exact = root(1.4 - 0.15j, 0.5, [(1, 0, 1)])
    print(f"Landau root (k = 0.5): omega = {exact.real:.5f}, gamma = {exact.imag:.5f}\n")
    print("| grid (x × v) | dt | peaks | gamma | rel. error | omega | rel. error | mass drift | energy drift |")
    print("|---|---|---|---|---|---|---|---|---|")
    hist_landau = None
    for nx, nv, dt, c in [(16, 64, 0.1, 0), (32, 128, 0.05, 0), (64, 256, 0.025, 0), (128, 512, 0.0125, 0),
                          (32, 128, 0.05, 1), (64, 256, 0.025, 1)]:
        out, h = R.run(f"landau_{nx}_{c}", "-fit", "landau", "-da_grid_x", str(nx), "-da_grid_y", str(nv), "-ts_dt",
                       str(dt), "-ts_max_time", "30", "-vlasov_dissipation", str(c))
        m = re.search(r"landau fit \((\d+) peaks\): gamma = (\S+) .*omega = (\S+) ", out)
        peaks, g, w = int(m.group(1)), float(m.group(2)), float(m.group(3))
        inv = re.search(r"mass (\S+), energy (\S+),", out)
        print(f"| {nx} × {nv}{' (c = 1)' if c else ''} | {dt} | {peaks} | {g:.5f} | {abs(g / exact.imag - 1):.1e} | {w:.5f} | "
              f"{abs(w / exact.real - 1):.1e} | {inv.group(1)} | {inv.group(2).rstrip(',')} |")
        if nx == 64 and c == 0:
            hist_landau = h
    t, W = hist_landau[:, 0], hist_landau[:, 1]
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.semilogy(t, W, lw=1, label="field energy W(t), 64 × 256")
    ax.semilogy(t, W[0] * 0.4 * np.exp(2 * exact.imag * t), "k--", lw=1, label=r"$\propto e^{2\gamma t}$, $\gamma$ = %.4f" % exact.imag)
    ax.set_xlabel("t")
    ax.set_ylabel("W")
    ax.set_title("Linear Landau damping, k = 0.5, alpha = 0.01")
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "vlasov_landau.png"), dpi=110)

    # 2. Two-stream linear growth against the dispersion relation, three temperature ratios.
    print("\n| temperature ratio r | dispersion relation omega | grid | measured gamma | rel. error |")
    print("|---|---|---|---|---|")
    fig, ax = plt.subplots(figsize=(7, 4))
    for r in [0.5, 1.0, 2.0]:
        w = root(0.01 + 0.2j, 0.2, two_stream_beams(r))
        for nx, nv in [(32, 128), (64, 256)]:
            out, h = R.run(f"ts_lin_{r}_{nx}", "-vlasov_ic", "two_stream", "-vlasov_alpha", "1e-7",
                           "-vlasov_temperature_ratio", str(r), "-da_grid_x", str(nx), "-da_grid_y", str(nv),
                           "-ts_dt", str(3.2 / nx), "-ts_max_time", "45", "-fit", "growth", "-fit_t0", "25",
                           "-fit_t1", "45")
            g = float(re.search(r"gamma = (\S+)", out).group(1))
            print(f"| {r} | {w.real:+.5f} {w.imag:+.5f}i | {nx} × {nv} | {g:.5f} | {abs(g / w.imag - 1):.1e} |")
            if nx == 64:
                line, = ax.semilogy(h[:, 0], h[:, 1], lw=1, label=f"r = {r}")
                ax.semilogy(h[:, 0], h[-1, 1] * np.exp(2 * w.imag * (h[:, 0] - h[-1, 0])), "--", lw=0.8,
                            color=line.get_color())
    ax.set_xlabel("t")
    ax.set_ylabel("W")
    ax.set_title(r"Two-stream growth (64 × 256, alpha = 1e-7); dashed: $e^{2\gamma t}$ from the dispersion relation")
    ax.title.set_fontsize(9)
    ax.legend()
    fig.tight_layout()
    fig.savefig(os.path.join(a.out, "vlasov_two_stream_growth.png"), dpi=110)

    # 3. Nonlinear two-stream run to saturation: phase space and invariants, two resolutions.
    times = [0, 20, 30, 40, 60]
    print("\n| grid | dt | dissipation c | mass drift | energy drift | L2 drift | max abs momentum change | min f at T = 60 (max f0 0.2) |")
    print("|---|---|---|---|---|---|---|---|")
    for nx, nv, dt, c in [(64, 128, 0.08, 0), (128, 256, 0.04, 0), (256, 512, 0.02, 0), (64, 128, 0.08, 1),
                          (128, 256, 0.04, 1), (256, 512, 0.02, 1)]:
        name = f"ts_nl_{nx}_{c}"
        out, h = R.run(name, "-vlasov_ic", "two_stream", "-da_grid_x", str(nx), "-da_grid_y", str(nv), "-ts_dt",
                       str(dt), "-ts_max_time", "60", "-snapshot_times", ",".join(map(str, times)),
                       "-vlasov_dissipation", str(c))
        inv = re.search(r"mass (\S+), energy (\S+), L2 norm (\S+); max \|momentum change\| (\S+);", out)
        fmin = snapshot(os.path.join(work, f"{name}_{len(times) - 1}.bin"), nx, nv).min()
        print(f"| {nx} × {nv} | {dt} | {c} | {inv.group(1)} | {inv.group(2)} | {inv.group(3)} | {inv.group(4)} | {fmin:.2e} |")
        if nx != 128:
            continue
        if c == 1:
            fig, axs = plt.subplots(1, 2, figsize=(9, 3.6), sharey=True)
            for ax, nm, title in [(axs[0], f"ts_nl_{nx}_0", "centred (c = 0)"), (axs[1], name, "-vlasov_dissipation 1")]:
                f = snapshot(os.path.join(work, f"{nm}_{len(times) - 1}.bin"), nx, nv)
                im = ax.imshow(f, origin="lower", aspect="auto", extent=[0, 2 * np.pi / 0.2, -8, 8], cmap="viridis",
                               vmin=-0.03, vmax=0.2)
                ax.set_title(f"t = 60, {title}")
                ax.set_xlabel("x")
            axs[0].set_ylabel("v")
            fig.colorbar(im, ax=axs, shrink=0.9)
            fig.savefig(os.path.join(a.out, "vlasov_two_stream_dissipation.png"), dpi=90)
            continue
        fig, axs = plt.subplots(1, len(times), figsize=(3.2 * len(times), 3.2), sharey=True)
        for n, (tt, ax) in enumerate(zip(times, axs)):
            f = snapshot(os.path.join(work, f"{name}_{n}.bin"), nx, nv)
            ax.imshow(f, origin="lower", aspect="auto", extent=[0, 2 * np.pi / 0.2, -8, 8], cmap="viridis")
            ax.set_title(f"t = {tt}")
            ax.set_xlabel("x")
        axs[0].set_ylabel("v")
        fig.suptitle("Two-stream instability, 128 × 256: f(x, v)")
        fig.tight_layout()
        fig.savefig(os.path.join(a.out, "vlasov_two_stream_phase_space.png"), dpi=90)
        t = h[:, 0]
        fig, axs = plt.subplots(1, 2, figsize=(11, 4))
        axs[0].semilogy(t, h[:, 1], lw=1)
        g = root(0.2j, 0.2, two_stream_beams(1.0)).imag
        i15, lin = np.argmin(abs(t - 15)), t <= 36
        axs[0].semilogy(t[lin], h[i15, 1] * np.exp(2 * g * (t[lin] - 15)), "k--", lw=0.8,
                        label=r"$e^{2\gamma t}$, $\gamma$ = %.4f (dispersion relation)" % g)
        axs[0].set_xlabel("t")
        axs[0].set_ylabel("field energy W")
        axs[0].legend()
        axs[0].set_title("growth and saturation")
        for col, lab in [(2, "mass"), (4, "total energy"), (5, "L2 norm")]:
            axs[1].semilogy(t[1:], np.abs(h[1:, col] / h[0, col] - 1) + 1e-17, lw=1, label=lab + " (relative)")
        axs[1].semilogy(t[1:], np.abs(h[1:, 3] - h[0, 3]) + 1e-17, lw=1, label="momentum (absolute)")
        axs[1].set_xlabel("t")
        axs[1].set_title("change of the invariants")
        axs[1].legend(fontsize=8)
        fig.tight_layout()
        fig.savefig(os.path.join(a.out, "vlasov_two_stream_history.png"), dpi=110)
    print(f"\n(data in {work})")


if __name__ == "__main__":
    main()
