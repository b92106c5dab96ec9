"""pyfem2d reaches the command line's numbers bit for bit."""

import json

import numpy as np
import pytest

import pyfem2d


def test_table1_equals_the_cli(fem2d):
    # Table 1 (case A, three energies, 2000 explicit steps each) from Python and from
    # `fem2d table1 --json`: the same tip displacements, to the last bit.
    cli = json.loads(fem2d("table1", "--json", "--repeats", "1").stdout)
    ours = pyfem2d.table1(repeats=1)
    assert [r["energy"] for r in ours["rows"]] == [r["energy"] for r in cli["rows"]]
    for a, b in zip(ours["rows"], cli["rows"]):
        assert a["ours_mm"] == b["ours_mm"], a["energy"]
        assert a["paper_mm"] == b["paper_mm"]
    assert ours["ordering_matches"] == cli["ordering_matches"]
    assert ours["setting"] == cli["setting"]


def last_frame(out_dir):
    lines = (out_dir / "frames.jsonl").read_text().splitlines()
    frame = json.loads(lines[-1])
    return frame


@pytest.mark.parametrize(
    "scene, args",
    [
        ("case-a", ["--energy", "neo-hookean", "--steps", "300"]),
        ("case-a", ["--energy", "stvk", "--solver", "implicit", "--dt", "0.01", "--steps", "40"]),
        ("case-c", ["--solver", "xpbd", "--steps", "200"]),
        # Bones as rigid bodies, debris, barrier contact: the medical scene.
        ("case-d", ["--steps", "25"]),
    ],
)
def test_stepped_from_python_equals_fem2d_run(fem2d, tmp_path, scene, args):
    out = tmp_path / "run"
    fem2d("run", scene, *args, "--set", "output.frame_every=1", "--out", str(out))
    frame = last_frame(out)
    summary = json.loads((out / "summary.json").read_text())

    kw = {}
    flags = dict(zip(args[::2], args[1::2]))
    if "--energy" in flags:
        kw["energy"] = flags["--energy"]
    if "--solver" in flags:
        kw["solver"] = flags["--solver"]
    if "--dt" in flags:
        kw["dt"] = float(flags["--dt"])
    steps = int(flags["--steps"])
    sim = pyfem2d.Simulation(scene, {"output.frame_every": 1}, steps=steps, **kw)
    # Step by step, as a real-time loop does.
    for _ in range(steps):
        sim.step()
    assert sim.steps_taken == frame["step"] == steps
    x = sim.positions()
    cli_x = np.asarray(frame["positions"], dtype=float).reshape(-1, 2)
    assert x.shape == cli_x.shape
    assert np.array_equal(x, cli_x), np.abs(x - cli_x).max()
    vm = sim.von_mises()
    cli_vm = np.array([np.nan if v is None else v for v in frame["von_mises"]])
    assert np.array_equal(vm, cli_vm, equal_nan=True)
    assert sim.time == frame["time"]

    # The whole run through pyfem2d.run: the CLI's summary (timings aside).
    result = pyfem2d.run(scene, {"output.frame_every": 1}, steps=steps, **kw)
    timing = {"wall_seconds", "step_seconds", "element_steps_per_second", "real_time_factor", "threads"}
    for key, value in summary.items():
        if key not in timing:
            assert result["summary"][key] == value, key
    assert np.array_equal(result["final_positions"], cli_x)


def test_overrides_as_strings_equal_overrides_as_a_dict():
    a = pyfem2d.Simulation("case-a", {"material.youngs_modulus": 2.5e3, "energy": "stvk"}, steps=20)
    b = pyfem2d.Simulation("case-a", ["material.youngs_modulus=2.5e3", 'energy="stvk"'], steps=20)
    a.step(20)
    b.step(20)
    assert a.energy == b.energy == "stvk"
    assert np.array_equal(a.positions(), b.positions())


def test_from_toml_equals_the_built_in_case():
    text = pyfem2d.case_text("case-a")
    a = pyfem2d.Simulation.from_toml(text, origin="case-a.toml")
    b = pyfem2d.Simulation("case-a")
    a.step(50)
    b.step(50)
    assert np.array_equal(a.positions(), b.positions())
    assert a.origin == "case-a.toml"
