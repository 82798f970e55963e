#!/usr/bin/env python3
"""Points per wavelength the wave's centred second differences need (-fd_order 2, 4, 8).

The semi-discrete 1D operator's phase velocity relative to c at a wave of PPW points per wavelength
(theta = 2 pi / PPW) is sqrt(s(theta)) / theta, s(theta) = -(w_0 + 2 sum_k w_k cos k theta) the
stencil's symbol (the weights of include/flexipde/differentiator.hpp). Prints, per order, the fewest
points per wavelength that keep the phase error below 1 %, 0.1 % and 0.01 %, and the error at 4-10.

    /usr/bin/python3 run/wave_dispersion.py
"""
import math

WEIGHTS = {2: [-2.0, 1.0], 4: [-30 / 12, 16 / 12, -1 / 12], 8: [-205 / 72, 8 / 5, -1 / 5, 8 / 315, -1 / 560]}


def phase_error(order, ppw):
    th = 2 * math.pi / ppw
    w = WEIGHTS[order]
    s = -(w[0] + 2 * sum(w[k] * math.cos(k * th) for k in range(1, len(w))))
    return math.sqrt(s) / th - 1


def points_needed(order, tol):
    # the error grows as PPW falls: the smallest PPW (to 0.1) from which on it stays within tol
    ppw = 200.0
    while ppw > 2.1 and abs(phase_error(order, ppw - 0.1)) <= tol:
        ppw -= 0.1
    return ppw


print("| -fd_order | PPW for 1 % | 0.1 % | 0.01 % | phase error at 4 / 5 / 6 / 8 / 10 PPW |")
print("|---|---:|---:|---:|---|")
for order in (2, 4, 8):
    need = " | ".join("%.1f" % points_needed(order, t) for t in (1e-2, 1e-3, 1e-4))
    errs = " / ".join("%.1e" % abs(phase_error(order, p)) for p in (4, 5, 6, 8, 10))
    print("| %d | %s | %s |" % (order, need, errs))
