"""Report for run/bench_peers.sh: reads the logs in OUT, compares the gradients, prints markdown.

    /usr/bin/python3 run/bench_peers.py OUT TORCH_STATUS SCALE
"""
import os
import re
import sys

import h5py
import numpy as np

out, torch_status, scale = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "1"


def read(name):
    with open(os.path.join(out, name)) as f:
        return f.read()


def timing(log):
    m = re.search(r"forward median ([0-9.]+) s \(min ([0-9.]+)\), gradient median ([0-9.]+) s \(min ([0-9.]+)\)", log)
    return tuple(float(v) for v in m.groups())


def peer(log):
    m = re.search(r"J = ([0-9.e+-]+), .*value\+gradient median ([0-9.]+) s \(min ([0-9.]+)\)", log)
    return float(m.group(1)), float(m.group(2)), float(m.group(3))


def reference_forward(log, kind="reference"):
    """The hand-written loop's forward alone (its line `<kind> forward: ...`), None if it printed none."""
    m = re.search(kind + r" forward: .*forward median ([0-9.]+) s", log)
    return float(m.group(1)) if m else None


f_fwd, _, f_grad, f_grad_min = timing(read("flexipde_leapfrog.log"))
r_fwd, _, r_grad, _ = timing(read("flexipde_rk4.log"))
J_ref, ref, ref_min = peer(read("reference.log"))
ref_fwd = reference_forward(read("reference.log"))
g_ref = np.loadtxt(os.path.join(out, "reference_gradient.txt"))
with h5py.File(os.path.join(out, "flexipde_gradient.h5"), "r") as h:
    g_flex = np.array(h["/gradient/dJdp"]).ravel()
    J_flex = float(np.array(h["/gradient/J"]).ravel()[0])
diff_flex = np.abs(g_flex - g_ref).max() / np.abs(g_ref).max()

rows = [("flexipde, -ts_type leapfrog", f_grad, f_fwd),
        ("flexipde, -ts_type rk (rk4)", r_grad, r_fwd),
        ("hand-written C leapfrog + adjoint (run/reference_leapfrog.c)", ref, ref_fwd)]
torch_line = None
if torch_status == 0:
    J_t, t_med, _ = peer(read("torch.log"))
    g_t = np.loadtxt(os.path.join(out, "torch_gradient.txt"))
    diff_t = np.abs(g_t - g_ref).max() / np.abs(g_ref).max()
    rows.append((re.search(r"torch ([^:]+):", read("torch.log")).group(0).rstrip(":") + " autograd (run/peer_torch.py)",
                 t_med, None))
    torch_line = (t_med, diff_t)
print("| value + gradient | median (s) | / hand-written | forward (s) | gradient / forward |")
print("|---|---|---|---|---|")
for name, t, fwd in rows:
    print("| %s | %.4f | %.2f | %s | %s |" % (name, t, t / ref, "%.4f" % fwd if fwd else "", "%.2f" % (t / fwd) if fwd else ""))
print()
print("- J: flexipde %.12e, reference %.12e; gradients (1000 entries) differ by %.1e relative (max norm)."
      % (J_flex, J_ref, diff_flex))
print("- flexipde leapfrog gradient / hand-written: **%.2f** (target <= 3); gradient / forward: **%.2f** (target <= 2.5)."
      % (f_grad / ref, f_grad / f_fwd))
print("- The hand-written loop's own value+gradient / forward (forward: three rolling rows, nothing stored): **%.2f**."
      % (ref / ref_fwd))
if torch_line:
    print("- PyTorch / flexipde leapfrog: **%.1f** (target >= 5); torch's gradient differs from the reference by %.1e."
          % (torch_line[0] / f_grad, torch_line[1]))
else:
    print("- PyTorch: skipped (python3-torch is not installed: `apt-get install python3-torch`).")

print()
print("Seed scene with the leapfrog on 1 and 2 ranks, one scalar speed or the 1000-entry field:")
print()
print("| ranks | parameters | forward (s) | value + gradient (s) | gradient / forward |")
print("|---|---|---|---|---|")
seed = {}
for np_ in (1, 2):
    for cf, params in ((0, 1), (1, 1000)):
        fwd, _, grad, _ = timing(read("seed_np%d_field%d.log" % (np_, cf)))
        seed[(np_, params)] = grad
        print("| %d | %d | %.4f | %.4f | %.2f |" % (np_, params, fwd, grad, grad / fwd))
print()
print("- Gradient time with 1000 parameters / with 1: %.2f (1 rank), %.2f (2 ranks)."
      % (seed[(1, 1000)] / seed[(1, 1)], seed[(2, 1000)] / seed[(2, 1)]))

print()
print("2D wave at the model survey's size (101 x 101 points, walls, 5000 leapfrog steps, field c), 1 core:")
print()
print("| | forward (s) | value + gradient (s) | gradient / forward |")
print("|---|---|---|---|")
sf, _, sg, _ = timing(read("small2d.log"))
ls2 = read("reference_small2d.log")
_, rg, _ = peer(ls2)
rf = reference_forward(ls2, "reference 2d")
print("| flexipde, -ts_type leapfrog | %.4f | %.4f | %.2f |" % (sf, sg, sg / sf))
print("| hand-written C (run/reference_leapfrog_2d.c) | %.4f | %.4f | %.2f |" % (rf, rg, rg / rf))
print()
print("- flexipde gradient / hand-written: %.2f; flexipde forward / hand-written forward: %.2f." % (sg / rg, sf / rf))

if scale:
    print()
    print("## Scale: 1D wave, 10^6 points, 200 leapfrog steps")
    print()
    print("| ranks | parameters | forward (s) | gradient (s) | forward Mpt-updates/s | gradient Mpt-updates/s |")
    print("|---|---|---|---|---|---|")
    n, steps = 1_000_000, 200
    grads = {}
    for np_ in (1, 2):
        for kind, params in (("scalar", 1), ("field", n)):
            fwd, _, grad, _ = timing(read("big_%s_np%d.log" % (kind, np_)))
            grads[(np_, kind)] = grad
            print("| %d | %d | %.4f | %.4f | %.1f | %.1f |" % (np_, params, fwd, grad, n * steps / fwd / 1e6,
                                                             n * steps / grad / 1e6))
    _, ref_big, _ = peer(read("reference_big.log"))
    print("| hand-written (1 core) | %d | | %.4f | | %.1f |" % (n, ref_big, n * steps / ref_big / 1e6))
    print()
    for np_ in (1, 2):
        print("- %d rank(s): gradient with 10^6 parameters / with 1 parameter = %.2f"
              % (np_, grads[(np_, "field")] / grads[(np_, "scalar")]))
    print("- 1 rank, 10^6 parameters: flexipde gradient / hand-written = %.2f" % (grads[(1, "field")] / ref_big))
    print()
    print("## Scale: 2D wave, 2000 x 2000 points, 100 leapfrog steps (no sponge)")
    print()
    print("| ranks | parameters | forward (s) | gradient (s) | gradient / forward | forward Mpt-updates/s | gradient Mpt-updates/s |")
    print("|---|---|---|---|---|---|---|")
    n, steps = 2000 * 2000, 100
    g2 = {}
    for np_ in (1, 2):
        for kind, params in (("scalar", 1), ("field", n)):
            fwd, _, grad, _ = timing(read("big2d_%s_np%d.log" % (kind, np_)))
            g2[(np_, kind)] = grad
            print("| %d | %d | %.3f | %.3f | %.2f | %.1f | %.1f |" % (np_, params, fwd, grad, grad / fwd,
                                                                   n * steps / fwd / 1e6, n * steps / grad / 1e6))
    log2d = read("reference_big2d.log")
    _, ref2d, _ = peer(log2d)
    rf = reference_forward(log2d, "reference 2d")
    if rf is not None:  # its forward alone (three rolling levels, nothing stored)
        print("| hand-written (1 core) | %d | %.3f | %.3f | %.2f | %.1f | %.1f |"
              % (n, rf, ref2d, ref2d / rf, n * steps / rf / 1e6, n * steps / ref2d / 1e6))
    else:
        print("| hand-written (1 core) | %d | | %.3f | | | %.1f |" % (n, ref2d, n * steps / ref2d / 1e6))
    print()
    for np_ in (1, 2):
        print("- %d rank(s): gradient with 4e6 parameters / with 1 parameter = %.2f"
              % (np_, g2[(np_, "field")] / g2[(np_, "scalar")]))
    print("- 1 rank, 4e6 parameters: flexipde gradient / hand-written = %.2f" % (g2[(1, "field")] / ref2d))
