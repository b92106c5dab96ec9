"""Bad input raises the documented exceptions with the command line's one-line messages."""

import json

import numpy as np
import pytest

import pyfem2d


def cli_error(fem2d, *args):
    done = fem2d(*args, check=False)
    assert done.returncode != 0
    line = done.stderr.strip().splitlines()[-1]
    assert line.startswith("error: ")
    return line[len("error: "):]


@pytest.mark.parametrize(
    "args, call",
    [
        (["run", "no-such-case"], lambda: pyfem2d.Simulation("no-such-case")),
        (
            ["run", "case-a", "--set", "material.youngs_modulus=-1"],
            lambda: pyfem2d.Simulation("case-a", {"material.youngs_modulus": -1}),
        ),
        (
            ["run", "case-a", "--solver", "nope"],
            lambda: pyfem2d.Simulation("case-a", solver="nope"),
        ),
        (
            ["run", "case-a", "--energy", "rubber"],
            lambda: pyfem2d.Simulation("case-a", energy="rubber"),
        ),
        (
            ["run", "case-a", "--set", "solver.dt=0"],
            lambda: pyfem2d.Simulation("case-a", ["solver.dt=0"]),
        ),
        (
            ["run", "case-a", "--set", "mesh.nx=two"],
            lambda: pyfem2d.Simulation("case-a", {"mesh.nx": "two"}),
        ),
    ],
)
def test_value_errors_carry_the_cli_message(fem2d, tmp_path, args, call):
    expected = cli_error(fem2d, *args, "--out", str(tmp_path / "out"))
    with pytest.raises(pyfem2d.InvalidInputError) as e:
        call()
    assert str(e.value) == expected
    assert isinstance(e.value, ValueError)
    assert isinstance(e.value, pyfem2d.Fem2dError)


def test_a_missing_file_is_a_file_error(tmp_path):
    with pytest.raises(pyfem2d.FileError) as e:
        pyfem2d.Simulation(str(tmp_path / "missing.toml"))
    assert isinstance(e.value, OSError)
    assert "missing.toml" in str(e.value)


def test_malformed_toml_names_the_origin():
    with pytest.raises(pyfem2d.InvalidInputError, match="my.toml"):
        pyfem2d.Simulation.from_toml("energy = [", origin="my.toml")


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"overrides": 5}, "overrides"),
        ({"overrides": "energy=stvk"}, "got a string"),
        ({"overrides": {"energy": object()}}, "overrides: energy"),
        ({"threads": 0}, "threads: 0"),
    ],
)
def test_bad_arguments(kwargs, match):
    with pytest.raises(pyfem2d.InvalidInputError, match=match):
        pyfem2d.Simulation("case-a", **kwargs)


def test_a_failed_step_stops_the_simulation_until_reset(fem2d, tmp_path):
    # Explicit StVK at 50 times its stable step blows up.
    args = ["--energy", "stvk", "--dt", "0.05", "--steps", "200"]
    out = tmp_path / "run"
    fem2d("run", "case-a", *args, "--out", str(out), check=False)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["blew_up"]
    sim = pyfem2d.Simulation("case-a", energy="stvk", dt=0.05, steps=200)
    with pytest.raises(pyfem2d.StepFailedError) as e:
        sim.run()
    assert str(e.value) == summary["blow_up_message"]
    assert sim.stopped == summary["blow_up_message"]
    with pytest.raises(pyfem2d.StepFailedError, match="reset"):
        sim.step()
    sim.reset()
    assert sim.stopped is None
    sim.step()


def test_no_panic_reaches_python():
    with pytest.raises(pyfem2d.InternalError) as e:
        pyfem2d._native._panic_for_tests()
    # An ordinary Exception (PyO3's PanicException is a BaseException).
    assert isinstance(e.value, Exception)
    assert "on purpose" in str(e.value)


def test_bad_run_arguments(beam=None):
    sim = pyfem2d.Simulation("case-a")
    with pytest.raises(pyfem2d.InvalidInputError, match="every"):
        sim.run(0.01, callback=lambda s: None, every=0)
    with pytest.raises(pyfem2d.InvalidInputError, match="seconds"):
        sim.run(-1.0)
    with pytest.raises(pyfem2d.InvalidInputError, match="seconds"):
        sim.run(float("inf"))


def test_a_callback_error_propagates():
    sim = pyfem2d.Simulation("case-a")

    def fail(_):
        raise RuntimeError("from the callback")

    with pytest.raises(RuntimeError, match="from the callback"):
        sim.run(0.01, callback=fail)
    sim.step()


def test_bad_mesh_inputs():
    with pytest.raises(pyfem2d.InvalidInputError, match="points"):
        pyfem2d.mesh_model(points=np.zeros((4, 2)), triangles=[[0, 1, 2]])
    with pytest.raises(pyfem2d.InvalidInputError, match="row 0 names vertex 7"):
        pyfem2d.mesh_model(points=np.zeros((4, 3)), triangles=[[0, 1, 7]])
    with pytest.raises(pyfem2d.InvalidInputError, match="view"):
        pyfem2d.mesh_model(points=np.zeros((4, 3)), triangles=[[0, 1, 2]], view="left")
    with pytest.raises(pyfem2d.InvalidInputError, match="either"):
        pyfem2d.mesh_model()
    with pytest.raises(pyfem2d.InvalidInputError):
        pyfem2d.mesh_model("/no/such/model.obj")
    with pytest.raises(pyfem2d.InvalidInputError, match="clockwise"):
        pyfem2d.mesh_json([[0, 0], [1, 0], [0, 1]], [[0, 2, 1]])


def test_bad_budget_arguments_name_them():
    with pytest.raises(pyfem2d.InvalidInputError, match="frameworks"):
        pyfem2d.budget("case-a", frameworks=["warp-drive"])
    with pytest.raises(pyfem2d.InvalidInputError, match="listed twice"):
        pyfem2d.budget("case-a", energies=["stvk", "stvk"])
    with pytest.raises(pyfem2d.InvalidInputError, match="fps"):
        pyfem2d.budget("case-a", fps=-1.0, energies=["stvk"], frameworks=["explicit"])
