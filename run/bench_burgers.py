"""Report for run/bench_burgers.sh: reads the logs in OUT, checks that flexipde's RK4 and the reference
agree (J and ||dJ/dnu|| to 1e-10), prints the markdown table (medians over rounds, ranges).

    python3 run/bench_burgers.py OUT ROUNDS < scenes      (scenes: "name N dt T nu nu_true field" lines)
"""
import os
import re
import statistics
import sys

out, rounds = sys.argv[1], int(sys.argv[2])
scenes = [line.split() for line in sys.stdin if line.strip()]


def read(name):
    path = os.path.join(out, name)
    return open(path).read() if os.path.exists(path) else None


def parse(log):
    """J, ||dJ/dp||, forward median, gradient median, fastest gradient (s) of one process."""
    j = re.search(r"gradient: J = ([^,]+), \|\|dJ/d\w+\|\| = ([0-9.eE+-]+|nan|-nan)", log)
    t = re.search(r"forward median ([0-9.]+) s .*gradient median ([0-9.]+) s \(min ([0-9.]+)", log)
    return float(j.group(1)), float(j.group(2)), float(t.group(1)), float(t.group(2)), float(t.group(3))


def cell(values, fmt):
    """median (min-max) of the values, or a dash if there are none; fmt a format or a function."""
    if not values:
        return "-"
    f = fmt if callable(fmt) else (lambda v: fmt % v)
    m = statistics.median(values)
    if len(values) == 1:
        return f(m)
    return "%s (%s-%s)" % (f(m), f(min(values)), f(max(values)))


def ms(v):
    """three significant digits, no exponent"""
    return "%.0f" % v if v >= 100 else "%.3g" % v
with open(os.path.join(out, "about.txt")) as f:
    about = dict(line.rstrip("\n").split(": ", 1) for line in f if ": " in line)
print("## Viscous Burgers gradient: flexipde against the hand-written RK4 and adjoint (1 core)")
print()
print("flexipde %s; measured %s; %s; load average after: %s." % (about.get("flexipde"), about.get("measured"),
                                                                  about.get("setup"), about.get("load average after")))
print("Times in ms: median over %d rounds of each process's median, (range over the rounds); ratios are formed "
      "per process (gradient/forward) or per round (flexipde / reference) and summarised the same way." % rounds)
print()
print("| scene | flexipde forward | flexipde gradient | gradient / forward | reference forward | reference gradient "
      "| reference gradient / forward | flexipde gradient / reference gradient |")
print("|---|---:|---:|---:|---:|---:|---:|---:|")
checks, fastest, failed = [], [], False
for name, n, dt, T, nu, nut, field in scenes:
    kind = "field nu (%s values)" % n if field == "1" else "scalar nu"
    steps = round(float(T) / float(dt))
    label = "N = %s, %s, %d steps" % (n, kind, steps)
    for ts in ("rk4", "cn"):
        fl, ref = [], []
        for r in range(1, rounds + 1):
            a = read("round%d_%s_%s.log" % (r, name, ts))
            if a is None:
                continue
            fl.append(parse(a))
            if ts == "rk4":
                ref.append(parse(read("round%d_%s_reference.log" % (r, name))))
        if not fl:
            continue
        row = ["%s, %s" % (label, "RK4" if ts == "rk4" else "CN (flexipde only)")]
        row.append(cell([1e3 * x[2] for x in fl], ms))
        row.append(cell([1e3 * x[3] for x in fl], ms))
        row.append(cell([x[3] / x[2] for x in fl], "%.2f"))
        if ref:
            row.append(cell([1e3 * x[2] for x in ref], ms))
            row.append(cell([1e3 * x[3] for x in ref], ms))
            row.append(cell([x[3] / x[2] for x in ref], "%.2f"))
            row.append("**" + cell([f[3] / g[3] for f, g in zip(fl, ref)], "%.2f") + "**")
            fastest.append("%s: %s" % (label, cell([f[4] / g[4] for f, g in zip(fl, ref)], "%.2f")))
            dj = max(abs(f[0] - g[0]) / abs(g[0]) for f, g in zip(fl, ref))
            dg = max(abs(f[1] - g[1]) / abs(g[1]) for f, g in zip(fl, ref))
            ok = dj <= 1e-10 and dg <= 1e-10
            failed |= not ok
            fd = re.findall(r"check: direction (\w+), .*relative difference ([0-9.e+-]+)",
                            read("round1_%s_reference.log" % name))
            checks.append("- %s: J = %.12e, ||dJ/dnu|| = %.12e; flexipde RK4 - reference: %.1e in J, %.1e in "
                          "||dJ/dnu|| (relative)%s; reference adjoint against central differences: %s."
                          % (label, fl[0][0], fl[0][1], dj, dg, "" if ok else " **above 1e-10**",
                             ", ".join("%s %s" % (d, v) for d, v in fd)))
        else:
            row += ["-"] * 4
        print("| " + " | ".join(row) + " |")
print()
print("flexipde gradient / reference gradient on each process's fastest repetition (less exposed to the time "
      "slices of other processes on a loaded machine): " + "; ".join(fastest) + ".")
print()
print("Agreement (every round):")
print()
print("\n".join(checks))
if failed:
    print()
    print("**flexipde's RK4 and the reference disagree above 1e-10 in at least one scene.**")
    sys.exit(1)
