#!/usr/bin/env python3
"""What the CPUs of a 2-CPU machine ran at the same moments, from `perf sched timehist`.

A lockstep run is a chain of waits: the vehicles wait for the clock master's release, the
master for the window's last state. Where the chain makes a CPU wait, it shows as time in
which one CPU runs one role and the other is idle. This reads the output of
`perf sched timehist` (one line per switch: when a task left a CPU, and how long it had
run), samples both CPUs every STEP_US and prints:
  - each CPU's share of time per role (vehicle, emulator, logger, leader, idle, other);
  - the pairs (what CPU 0 ran, what CPU 1 ran), unordered, by their share of time.

Usage:
  perf sched record -a -o sched.data -- sleep 1.5     # while a run goes on
  perf sched timehist -i sched.data > timehist.txt
  bench/cpu_overlap.py timehist.txt [STEP_US]          # STEP_US: 10 by default
"""
import bisect
import collections
import sys


def role(task):
    name = task.split("[")[0]
    if name.startswith("<idle>"):
        return "idle"
    for key, label in (("vehicle", "vehicle"), ("channel_e", "emulator"),
                       ("lcm-logger", "logger"), ("leader", "leader")):
        if key in name:
            return label
    return "other"


def read(path):
    """Per CPU, the intervals (start s, end s, role) it ran, in order."""
    runs = collections.defaultdict(list)
    with open(path) as f:
        for line in f:
            p = line.split()
            if len(p) < 6:
                continue
            try:
                t, cpu, ran_ms = float(p[0]), int(p[1].strip("[]")), float(p[-1])
            except ValueError:
                continue  # the header
            runs[cpu].append((t - ran_ms / 1000, t, role(" ".join(p[2:-3]))))
    for cpu in runs:
        runs[cpu].sort()
    return runs


def main():
    if len(sys.argv) >= 2 and sys.argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        return 0
    if len(sys.argv) < 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    step = (float(sys.argv[2]) if len(sys.argv) > 2 else 10.0) * 1e-6
    runs = read(sys.argv[1])
    if sorted(runs) != [0, 1]:
        print("cpu_overlap: needs the switches of exactly CPUs 0 and 1, got %s" % sorted(runs),
              file=sys.stderr)
        return 2
    t0 = max(runs[c][0][0] for c in runs)
    t1 = min(runs[c][-1][1] for c in runs)
    starts = {c: [r[0] for r in runs[c]] for c in runs}

    def at(c, t):
        i = bisect.bisect_right(starts[c], t) - 1
        return runs[c][i][2] if i >= 0 and runs[c][i][0] <= t < runs[c][i][1] else "idle"

    per_cpu = collections.Counter()
    pairs = collections.Counter()
    n = 0
    t = t0
    while t < t1:
        a, b = at(0, t), at(1, t)
        per_cpu[(0, a)] += 1
        per_cpu[(1, b)] += 1
        pairs[tuple(sorted((a, b)))] += 1
        n += 1
        t += step
    print("%.3f s sampled every %.0f us" % (t1 - t0, step * 1e6))
    for cpu in (0, 1):
        shares = sorted(((v, r) for (c, r), v in per_cpu.items() if c == cpu), reverse=True)
        print("cpu %d: %s" % (cpu, ", ".join("%s %.1f %%" % (r, 100.0 * v / n)
                                            for v, r in shares)))
    print("both CPUs at once:")
    for (a, b), v in pairs.most_common():
        print("  %-8s + %-8s %5.1f %%" % (a, b, 100.0 * v / n))
    return 0


if __name__ == "__main__":
    sys.exit(main())
