"""The per-step overhead of driving a scene from Python (a benchmark, not a test).

    python crates/fem-py/bench/overhead.py [--scene case-d] [--steps N] [--repeats R]

Times the same steps two ways in one process, from the same state (a snapshot restored before
each timing), in R adjacent pairs:

- Python: a loop of ``sim.step()``, ``sim.positions(out=x)`` and ``sim.von_mises(out=vm)``,
  the real-time loop of docs/python.md;
- Rust: ``pyfem2d._native._rust_loop(sim, N)``, the same step, the same copies of positions
  and von Mises into buffers, in a Rust loop with the GIL released once.

The overhead is Python / Rust - 1: the median over the pairs (each pair's two loops run back to
back, so they share the machine's state; the median is robust to a pair a busy machine
disturbed), and the ratio of the two bests. Run on the release build (`cargo xtask python
--bench`).
"""

import argparse
import time

import numpy as np

import pyfem2d
from pyfem2d import _native


def python_loop(sim, n, x, vm):
    start = time.perf_counter()
    for _ in range(n):
        sim.step()
        sim.positions(out=x)
        sim.von_mises(out=vm)
    return time.perf_counter() - start


def measure(scene, overrides, steps, repeats, threads):
    sim = pyfem2d.Simulation(scene, overrides, threads=threads)
    sim.step(3)  # past the first step's set-up
    snap = sim.snapshot()
    x = np.empty((sim.n_vertices, 2))
    vm = np.empty(sim.n_triangles)
    pairs = []
    for _ in range(repeats):
        sim.restore(snap)
        py = python_loop(sim, steps, x, vm)
        after_py = sim.positions()
        sim.restore(snap)
        rs = _native._rust_loop(sim, steps)
        # The two loops took the same steps.
        assert np.array_equal(sim.positions(), after_py)
        pairs.append((py, rs))
    return sim, pairs


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", action="append", help="scene (repeatable; default case-d and case-a)")
    p.add_argument("--steps", type=int, default=100)
    p.add_argument("--repeats", type=int, default=21)
    p.add_argument("--threads", type=int, default=None,
                   help="a pool of this many threads for the simulation (default: rayon's own)")
    args = p.parse_args()
    scenes = args.scene or ["case-d", "case-a"]
    print(f"pyfem2d {pyfem2d.__version__}; {args.repeats} pairs of {args.steps} steps, "
          f"threads: {args.threads or 'rayon default'}")
    print("| scene | solver | triangles | Rust ms/step (best) | Python ms/step (best) "
          "| overhead, median of pairs | overhead, bests |")
    print("|---|---|---|---|---|---|---|")
    for scene in scenes:
        sim, pairs = measure(scene, None, args.steps, args.repeats, args.threads)
        py = min(p for p, _ in pairs)
        rs = min(r for _, r in pairs)
        median = float(np.median([p / r - 1 for p, r in pairs]))
        per_py, per_rs = 1e3 * py / args.steps, 1e3 * rs / args.steps
        print(f"| {scene} | {sim.solver} | {sim.n_triangles} | {per_rs:.4f} | {per_py:.4f} | "
              f"{100 * median:+.1f} % | {100 * (py - rs) / rs:+.1f} % "
              f"({1e6 * (py - rs) / args.steps:.1f} us/step) |")


if __name__ == "__main__":
    main()
