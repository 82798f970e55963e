"""The seed FWI problem in PyTorch autograd: the autodiff peer of run/bench_peers.sh.

Same scheme as run/reference_leapfrog.c and flexipde's -ts_type leapfrog (Stormer-Verlet in
position form on u_tt = c(x)^2 u_xx, u = 0 at the walls, u_0 a Gaussian of width 0.2 at 0.5,
v_0 = -c u_0'), J = 0.5 ||u_n - d||^2 with d from c = 1, gradient by reverse-mode autograd with
respect to the 1000-entry field c. float64, one thread (torch.set_num_threads(1)).

    /usr/bin/python3 run/peer_torch.py [n] [steps] [dt] [c0] [repeats] [gradient_out]

prints J, ||dJ/dc|| and the median wall time of value+gradient; exits 3 when torch is absent.
"""
import sys
import time

try:
    import torch
except ImportError:
    print("peer_torch: python3-torch is not installed; skipped")
    sys.exit(3)


def run(n=1000, steps=5000, dt=5e-4, c0=0.9, repeats=5, out=None):
    torch.set_num_threads(1)
    dtype = torch.float64
    h = 1.0 / (n - 1)
    x = torch.arange(n, dtype=dtype) * h
    s = (x - 0.5) / 0.2
    u0 = torch.exp(-s * s)
    du0 = -2 * s / 0.2 * u0
    interior = torch.ones(n, dtype=dtype)
    interior[0] = interior[-1] = 0
    u0 = u0 * interior
    du0 = du0 * interior

    def d2(u):
        out = torch.zeros_like(u)
        out[1:-1] = (u[:-2] - 2 * u[1:-1] + u[2:]) / (h * h)
        return out

    def final_state(c):
        v0 = -c * du0 * interior
        um = u0
        uk = (u0 + dt * v0 + 0.5 * dt * dt * c * c * d2(u0)) * interior
        for _ in range(1, steps):
            um, uk = uk, (2 * uk - um + dt * dt * c * c * d2(uk)) * interior
        return uk

    with torch.no_grad():
        d = final_state(torch.ones(n, dtype=dtype))
    times = []
    for _ in range(repeats):
        c = torch.full((n,), c0, dtype=dtype, requires_grad=True)
        t0 = time.perf_counter()
        J = 0.5 * torch.sum((final_state(c) - d) ** 2)
        J.backward()
        times.append(time.perf_counter() - t0)
    times.sort()
    m = len(times)
    median = times[m // 2] if m % 2 else 0.5 * (times[m // 2 - 1] + times[m // 2])
    g = c.grad.detach()
    print("torch %s: n %d, %d steps of %g, J = %.12e, ||dJ/dc|| = %.12e, value+gradient median %.6f s (min %.6f) over %d"
          % (torch.__version__, n, steps, dt, J.item(), torch.linalg.norm(g).item(), median, times[0], m))
    if out:
        with open(out, "w") as f:
            for v in g.tolist():
                f.write("%.17e\n" % v)


if __name__ == "__main__":
    a = sys.argv[1:]
    run(int(a[0]) if len(a) > 0 else 1000, int(a[1]) if len(a) > 1 else 5000, float(a[2]) if len(a) > 2 else 5e-4,
        float(a[3]) if len(a) > 3 else 0.9, int(a[4]) if len(a) > 4 else 5, a[5] if len(a) > 5 else None)
