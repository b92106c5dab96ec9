"""A tour of pyfem2d: Table 1, case C's tip curves, and a loop that drags the beam.

    python examples/python/tour.py [--out DIR] [--quick]

Prints Table 1 beside the paper's values, runs case C under explicit FEM, PBD and XPBD, and
drags case A's tip up and down from a Python loop as a controller would (a spring grab, moved
every frame, positions read into preallocated buffers). With matplotlib installed it saves
`tip-curves.png` and `drag.png` into DIR (default: the current directory).
"""

import argparse
import math
from pathlib import Path

import numpy as np

import pyfem2d


def table1():
    t = pyfem2d.table1()
    print(f"Table 1 ({t['setting']})")
    print("energy               frame 10   frame 50  frame 120  frame 200   (mm; paper in brackets)")
    for row in t["rows"]:
        cells = "  ".join(f"{o:7.1f} [{p:4.0f}]" for o, p in zip(row["ours_mm"], row["paper_mm"]))
        print(f"{row['energy']:<20} {cells}")
    return t


def case_c_tip_curves(quick):
    curves = {}
    for solver in ("explicit", "pbd", "xpbd"):
        steps = None if not quick else 200
        r = pyfem2d.run("case-c", solver=solver, steps=steps)
        tip = r["probes"]["tip"]
        curves[solver] = (r["frame_times"], tip[:, 1])
        s = r["summary"]
        print(f"case C, {solver:<8}: tip uy at the end {1e3 * tip[-1, 1]:8.2f} mm, "
              f"{s['element_steps_per_second']:.3g} element-steps/s")
    return curves


def drag_the_beam(quick):
    sim = pyfem2d.Simulation("case-a", energy="neo-hookean")
    rest = sim.rest_positions()
    right = rest[:, 0].max()
    tip = int(np.flatnonzero(np.isclose(rest[:, 0], right))[0])
    x = np.empty((sim.n_vertices, 2))
    vm = np.empty(sim.n_triangles)
    sim.grab(*rest[tip], stiffness=500.0)
    frames = 90 if quick else 270
    per_frame = max(1, round((1 / 90) / sim.dt))
    trace = []
    for f in range(frames):
        t = f / 90
        hand = rest[tip] + np.array([0.0, 0.8 * math.sin(2 * math.pi * 0.5 * t)])
        sim.move_to(*hand)
        sim.step(per_frame)
        sim.positions(out=x)
        sim.von_mises(out=vm)
        trace.append((sim.time, hand[1], x[tip, 1], vm.max()))
    trace = np.array(trace)
    print(f"drag: {frames} frames of {per_frame} steps; tip followed the hand within "
          f"{np.abs(trace[:, 2] - trace[:, 1]).max():.3f} m; peak von Mises {trace[:, 3].max():.3g} Pa")
    return trace


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("."))
    parser.add_argument("--quick", action="store_true", help="shorter runs")
    args = parser.parse_args()
    table1()
    curves = case_c_tip_curves(args.quick)
    trace = drag_the_beam(args.quick)
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib is not installed: no plots")
        return
    args.out.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    for solver, (t, uy) in curves.items():
        ax.plot(t, 1e3 * uy, label=solver)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("tip uy (mm)")
    ax.set_title("Case C: tip deflection")
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out / "tip-curves.png", dpi=120)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(trace[:, 0], trace[:, 1], label="hand")
    ax.plot(trace[:, 0], trace[:, 2], label="tip")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("y (m)")
    ax.set_title("Case A dragged by a spring from Python")
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out / "drag.png", dpi=120)
    print(f"wrote {args.out / 'tip-curves.png'} and {args.out / 'drag.png'}")


if __name__ == "__main__":
    main()
