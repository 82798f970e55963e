#!/usr/bin/env python3
"""The seed JAX notebook's FWI problem, in numpy (float64), as an independent reference for the
notebook scenes (examples/scenes/notebook_fwi_*.opts).

Problem: n = 1000 points on [0, 1], dx = 1/(n-1), dt = 5e-4. Two-level start
    u^0 = exp(-(5(x-0.5))^2),   u^1 = exp(-(5(x-0.5-c dt))^2)     (pointwise in c for a field),
then 5000 steps of the leapfrog recurrence on ALL n points, the neighbours outside the grid zero:
    u^{k+1}_i = 2 u^k_i - u^{k-1}_i + (c_i dt/dx)^2 (u^k_{i+1} - 2 u^k_i + u^k_{i-1}),
giving u^2 .. u^5001. Objective J(c) = ||u^5001 - d|| (the norm, not its square), d from the true c.

The gradient is a hand-written reverse sweep of the recurrence, checked here by the complex step
on a few entries. Optional optimisers reproduce the notebook's runs: optax's Adam
(--adam ITER, lr 1e-3, b1 0.9, b2 0.999, eps 1e-8) and scipy's L-BFGS-B.

    /usr/bin/python3 run/notebook_reference.py               # losses, gradients, complex-step checks
    /usr/bin/python3 run/notebook_reference.py --adam 1000   # + Adam, constant and linear cases
    /usr/bin/python3 run/notebook_reference.py --adam 1000 --perturb 5
                     # + 5 linear Adam runs whose gradients are multiplied by 1 + 1e-12 N(0, 1)
    /usr/bin/python3 run/notebook_reference.py --lbfgs       # + L-BFGS-B on the linear case
"""
import argparse
import sys
import time

import numpy as np

N_POINTS = 1000
DT = 5e-4
STEPS = 5000  # recurrence steps after the two given levels: u^2 .. u^5001


def grid(n=N_POINTS):
    x = np.linspace(0.0, 1.0, n)
    return x, 1.0 / (n - 1)


def lap(u):
    """u_{i+1} - 2 u_i + u_{i-1} with zeros outside the grid (every point updated)."""
    out = -2.0 * u
    out[1:] += u[:-1]
    out[:-1] += u[1:]
    return out


def start(x, c, dt=DT):
    u0 = np.exp(-(5.0 * (x - 0.5)) ** 2)
    u1 = np.exp(-(5.0 * (x - 0.5 - c * dt)) ** 2)
    return u0, u1


def forward(c, x, dx, dt=DT, steps=STEPS, keep=False):
    """u^{steps+1}; with keep, every level u^0 .. u^{steps+1} as well."""
    c = np.broadcast_to(c, x.shape)
    r = (c * dt / dx) ** 2
    um, u = start(x, c, dt)
    levels = [um, u] if keep else None
    for _ in range(steps):
        um, u = u, 2.0 * u - um + r * lap(u)
        if keep:
            levels.append(u)
    return u, levels


def loss(c, d, x, dx):
    u, _ = forward(c, x, dx)
    e = u - d
    return np.sqrt(np.sum(e * e))  # no abs: also right for the complex step


def loss_and_gradient(c, d, x, dx, dt=DT, steps=STEPS, scalar=False):
    """J and dJ/dc by the reverse sweep (dJ/dc summed for a scalar c)."""
    cf = np.broadcast_to(np.asarray(c, dtype=float), x.shape)
    r = (cf * dt / dx) ** 2
    u, levels = forward(cf, x, dx, dt, steps, keep=True)
    e = u - d
    J = np.sqrt(np.sum(e * e))
    # a^k = dJ/du^k. u^{k+1} = 2 u^k - u^{k-1} + r (L u^k), L symmetric:
    #   a^k = 2 a^{k+1} + L (r a^{k+1}) - a^{k+2}   (k >= 1),   a^0 = -a^2 (u^0 enters u^2 only),
    #   dJ/dr = sum_{k>=1} a^{k+1} (L u^k).
    N = steps + 1
    a_next, a_next2 = e / J, np.zeros_like(e)  # a^N, a^{N+1}
    g_r = np.zeros_like(e)
    for k in range(N - 1, 0, -1):
        g_r += a_next * lap(levels[k])
        a_k = 2.0 * a_next + lap(r * a_next) - a_next2
        a_next2, a_next = a_next, a_k
    a1, a2 = a_next, a_next2  # a^1, a^2
    # u^0 does not depend on c; u^1_i = exp(-s_i^2), s = 5(x - 0.5 - c dt): du^1/dc = 10 dt s exp(-s^2)
    s = 5.0 * (x - 0.5 - cf * dt)
    du1 = 10.0 * dt * s * np.exp(-s * s)
    g = g_r * 2.0 * cf * (dt / dx) ** 2 + a1 * du1
    del a2
    return J, (np.sum(g) if scalar else g)


def complex_step(c, d, x, dx, index=None, h=1e-30):
    """dJ/dc_index (dJ/dc for a scalar c, index None) by the complex step."""
    cc = np.array(c, dtype=complex)
    if index is None:
        cc = cc + 1j * h
    else:
        cc[index] += 1j * h
    return loss(cc, d, x, dx).imag / h


def adam(c, d, x, dx, iterations, lr=1e-3, b1=0.9, b2=0.999, eps=1e-8, scalar=False, log=None, noise=None,
         truth=None):
    """optax.adam: m, v moments, bias-corrected, update -lr mhat / (sqrt(vhat) + eps). noise: a numpy
    Generator; each gradient is then multiplied by 1 + 1e-12 N(0, 1) (a round-off-sized change). log: print
    J (and the RMSE against truth) of iterate k every log iterations, numbered as TAO numbers them."""
    c = np.array(c, dtype=float)
    m = np.zeros_like(c)
    v = np.zeros_like(c)
    for t in range(1, iterations + 1):
        J, g = loss_and_gradient(c, d, x, dx, scalar=scalar)
        if log and (t - 1) % log == 0:
            e = f", RMSE = {rmse(c, truth):.6f}" if truth is not None else ""
            print(f"  adam {t - 1:5d}: J = {J:.6e}{e}", flush=True)
        if noise is not None:
            g = g * (1 + 1e-12 * noise.standard_normal(np.shape(g)))
        m = b1 * m + (1 - b1) * g
        v = b2 * v + (1 - b2) * g * g
        mhat = m / (1 - b1 ** t)
        vhat = v / (1 - b2 ** t)
        c = c - lr * mhat / (np.sqrt(vhat) + eps)
    return c


def rmse(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--adam", type=int, default=0, help="Adam iterations on both cases (0: none)")
    ap.add_argument("--perturb", type=int, default=0,
                    help="with --adam: that many more linear Adam runs with gradients perturbed by 1e-12 (seeds 1..K)")
    ap.add_argument("--lbfgs", action="store_true",
                    help="scipy L-BFGS-B on the linear case: gtol 1e-5 alone, and tol=1e-5 (ftol and gtol)")
    args = ap.parse_args()
    x, dx = grid()
    ok = True

    # linear case: data from linspace(0.9, 1.0), start linspace(0.85, 1.0)
    c_true = np.linspace(0.9, 1.0, N_POINTS)
    c0 = np.linspace(0.85, 1.0, N_POINTS)
    d, _ = forward(c_true, x, dx)
    t0 = time.time()
    J, g = loss_and_gradient(c0, d, x, dx)
    gn = np.linalg.norm(g)
    print(f"linear:   J = {J:.6f}, ||dJ/dc|| = {gn:.6f}, dJ/dc in [{g.min():.6f}, {g.max():.6f}]"
          f"   (notebook float64: 3.944720, 4.976304; float32 range [-0.264329, -0.000011])"
          f"  [{time.time() - t0:.1f} s]")
    ok &= f"{J:.6f}" == "3.944720" and f"{gn:.6f}" == "4.976304"
    for i in (0, 1, 250, 500, 998, 999):
        cs = complex_step(c0, d, x, dx, i)
        print(f"  dJ/dc[{i:3d}]: reverse sweep {g[i]: .12e}, complex step {cs: .12e}, rel. diff "
              f"{abs(g[i] - cs) / abs(cs):.1e}")
        ok &= abs(g[i] - cs) <= 1e-9 * abs(cs)

    # constant case: data from c = 1.0, start c = 0.8
    dc, _ = forward(1.0, x, dx)
    Jc, gc = loss_and_gradient(0.8, dc, x, dx, scalar=True)
    cs = complex_step(0.8, dc, x, dx)
    # The notebook printed 15.758533 in float32; float32 loops that differ only in the order of the
    # stencil's additions give 15.7576-15.7617 here (the linear case 3.9442-3.9451): float64 is 15.757648.
    print(f"constant: J = {Jc:.6f}, dJ/dc = {gc:.9e} (complex step {cs:.9e})   (notebook float32: 15.758533)")
    ok &= f"{Jc:.6f}" == "15.757648" and abs(gc - cs) <= 1e-9 * abs(cs)

    if args.adam:
        t0 = time.time()
        cA = adam(0.8, dc, x, dx, args.adam, scalar=True, log=100)
        print(f"constant, Adam {args.adam}: c = {float(cA):.6f}   (notebook: 0.999937)  [{time.time() - t0:.0f} s]")
        t0 = time.time()
        cL = adam(c0, d, x, dx, args.adam, log=100, truth=c_true)
        print(f"linear, Adam {args.adam}: RMSE = {rmse(cL, c_true):.6f}   (notebook: 0.016962)  [{time.time() - t0:.0f} s]")
        for seed in range(1, args.perturb + 1):
            cP = adam(c0, d, x, dx, args.adam, noise=np.random.default_rng(seed), log=100, truth=c_true)
            print(f"linear, Adam {args.adam}, gradients perturbed by 1e-12 (seed {seed}): RMSE = {rmse(cP, c_true):.6f}",
                  flush=True)
    if args.lbfgs:
        from scipy.optimize import minimize
        fg = lambda c: loss_and_gradient(c, d, x, dx)
        for label, kw in [("gtol 1e-5, at most 1000 iterations", dict(options={"gtol": 1e-5, "maxiter": 1000})),
                          ("tol=1e-5 (ftol and gtol)", dict(tol=1e-5))]:
            t0 = time.time()
            res = minimize(fg, c0, jac=True, method="L-BFGS-B", **kw)
            print(f"linear, L-BFGS-B {label}: {res.nit} iterations, {res.nfev} evaluations, J = {res.fun:.3e}, "
                  f"RMSE = {rmse(res.x, c_true):.6f}   (notebook: 0.014198)  [{time.time() - t0:.0f} s]")
    print("reference: " + ("ok" if ok else "MISMATCH"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
