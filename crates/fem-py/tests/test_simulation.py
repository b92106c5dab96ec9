"""The Simulation API: arrays, out= buffers, snapshots, the hand, run loops, threads."""

import _thread
import threading
import time

import numpy as np
import pytest

import pyfem2d


@pytest.fixture
def beam():
    return pyfem2d.Simulation("case-a", energy="neo-hookean")


def test_arrays_have_the_documented_shapes_and_types(beam):
    beam.step(10)
    n, m = beam.n_vertices, beam.n_triangles
    for a in (beam.positions(), beam.velocities(), beam.displacements(), beam.rest_positions()):
        assert a.shape == (n, 2) and a.dtype == np.float64
    t = beam.triangles()
    assert t.shape == (m, 3) and t.dtype == np.int64
    assert t.min() == 0 and t.max() == n - 1
    for a in (beam.von_mises(), beam.det_f()):
        assert a.shape == (m,) and a.dtype == np.float64
    assert beam.region_tags().shape == (m,) and beam.region_tags().dtype == np.int64
    assert beam.region_names() == ["body"]
    assert beam.contact_pressure().shape == (n,)
    assert np.array_equal(beam.displacements(), beam.positions() - beam.rest_positions())
    r = beam.report
    assert r.iterations == 0 and r.inverted == 0 and 0.9 < r.min_det_f <= 1.0 + 1e-9
    # A copy by default: changing it does not change the simulation.
    x = beam.positions()
    x[:] = 0.0
    assert not np.array_equal(beam.positions(), x)


def test_out_buffers_are_filled_in_place(beam):
    beam.step(5)
    x = np.empty((beam.n_vertices, 2))
    vm = np.empty(beam.n_triangles)
    assert beam.positions(out=x) is x
    assert beam.von_mises(out=vm) is vm
    assert np.array_equal(x, beam.positions())
    assert np.array_equal(vm, beam.von_mises())
    with pytest.raises(pyfem2d.InvalidInputError, match="shape"):
        beam.positions(out=np.empty((3, 2)))
    with pytest.raises(pyfem2d.InvalidInputError, match="C-contiguous"):
        beam.positions(out=np.empty((2, beam.n_vertices)).T)
    with pytest.raises(TypeError):
        beam.positions(out=np.empty((beam.n_vertices, 2), dtype=np.float32))


def test_snapshot_and_restore_continue_bit_for_bit():
    for solver in ("explicit", "implicit"):
        sim = pyfem2d.Simulation("case-a", solver=solver, dt=0.01 if solver == "implicit" else None)
        sim.step(20)
        snap = sim.snapshot()
        assert snap.step == 20 and snap.time == sim.time
        sim.step(15)
        a = sim.positions()
        sim.restore(snap)
        assert sim.steps_taken == 20
        sim.step(15)
        assert np.array_equal(sim.positions(), a), solver
    other = pyfem2d.Simulation("case-a", {"mesh.nx": 10})
    with pytest.raises(pyfem2d.InvalidInputError, match="snapshot"):
        other.restore(snap)


def test_reset_goes_back_to_the_start(beam):
    x0 = beam.positions()
    beam.step(30)
    beam.reset()
    assert beam.time == 0.0 and beam.steps_taken == 0
    assert np.array_equal(beam.positions(), x0)


def tip_vertex(sim):
    rest = sim.rest_positions()
    # The free end's lowest corner, where case A's tip probe sits.
    right = rest[:, 0].max()
    candidates = np.flatnonzero(np.isclose(rest[:, 0], right))
    return candidates[np.argmin(rest[candidates, 1])]


@pytest.mark.parametrize("stiffness", [0.0, 200.0])
def test_a_grab_moves_the_body(stiffness):
    free = pyfem2d.Simulation("case-a", energy="neo-hookean")
    held = pyfem2d.Simulation("case-a", energy="neo-hookean")
    k = tip_vertex(held)
    p = held.rest_positions()[k]
    assert held.grab(p[0], p[1], stiffness=stiffness)
    assert held.held == "body"
    # A hand lifts the tip by half a metre over 0.3 s, as a controller would, frame by frame.
    for f in range(1, 101):
        held.move_to(p[0], p[1] + 0.5 * f / 100)
        held.step(3)
    free.step(300)
    # Gravity pulls the free tip down by a metre; the hand holds the tip up.
    assert free.displacements()[k, 1] < -0.5
    assert held.displacements()[k, 1] > 0.3
    if stiffness > 0:
        fx, fy = held.grab_force()
        assert fy > 0.0
    lifted = held.displacements()[k, 1]
    held.release()
    assert held.held == "nothing" and held.grab_force() is None
    held.step(500)
    # Let go, the bent beam springs up a little, then falls back below where it was held.
    assert held.displacements()[k, 1] < lifted - 0.3


def test_grab_outside_the_body_grabs_nothing(beam):
    assert not beam.grab(100.0, 100.0)
    assert beam.held == "nothing"
    with pytest.raises(pyfem2d.InvalidInputError, match="not finite"):
        beam.grab(float("nan"), 0.0)


def test_run_with_a_callback_every_n_steps(beam):
    seen = []

    def callback(sim):
        seen.append(sim.steps_taken)

    taken = beam.run(0.1, callback=callback, every=25)
    assert taken == 100 == beam.steps_taken
    assert seen == [25, 50, 75, 100]
    # A callback that returns False stops the run.
    stopped = beam.run(1.0, callback=lambda sim: sim.steps_taken < 150, every=10)
    assert beam.steps_taken == 150 and stopped == 50


def test_run_without_seconds_runs_to_the_scene_end():
    sim = pyfem2d.Simulation("case-a", steps=120)
    sim.step(20)
    assert sim.run() == 100 and sim.steps_taken == 120
    assert sim.run() == 0
    static = pyfem2d.Simulation("case-a", solver="static")
    static.run()
    assert static.time == pytest.approx(1.0)
    with pytest.raises(pyfem2d.InvalidInputError, match="load factor"):
        static.run(1.0)


@pytest.mark.parametrize("how", ["run", "step"])
def test_ctrl_c_interrupts_a_long_run(how):
    sim = pyfem2d.Simulation("case-d")
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        if how == "run":
            sim.run(1e6)
        else:
            sim.step(10**9)
    timer.cancel()
    assert time.monotonic() - start < 30.0
    # Interrupted between steps: the state is whole and stepping goes on.
    assert sim.steps_taken > 0
    assert np.isfinite(sim.positions()).all()
    sim.step()


def test_steps_release_the_gil():
    sim = pyfem2d.Simulation("case-d")
    count = [0]
    done = threading.Event()

    def spin():
        while not done.is_set():
            count[0] += 1

    t = threading.Thread(target=spin)
    t.start()
    try:
        time.sleep(0.05)
        before = count[0]
        sim.step(40)  # hundreds of milliseconds in Rust
        during = count[0] - before
    finally:
        done.set()
        t.join()
    # With the GIL held the spinning thread could not have counted at all during the call.
    assert during > 1000


def test_threads_give_the_same_bits():
    a = pyfem2d.Simulation("case-d", threads=1)
    b = pyfem2d.Simulation("case-d", threads=2)
    a.step(10)
    b.step(10)
    assert a.threads == 1 and b.threads == 2
    assert np.array_equal(a.positions(), b.positions())
    assert np.array_equal(a.von_mises(), b.von_mises(), equal_nan=True)


def test_case_d_contacts_pressure_and_regions():
    sim = pyfem2d.Simulation("case-d")
    sim.run(0.4)
    c = sim.contacts()
    k = len(c["kind"])
    assert k > 0
    assert c["point"].shape == (k, 2) and c["normal"].shape == (k, 2)
    assert c["gap"].shape == (k,) and (c["force"] >= 0).all()
    assert set(c["kind"]) <= {"vertex-ground", "vertex-obstacle", "corner-edge"}
    assert sim.contact_pressure().max() > 0.0
    names = sim.region_names()
    assert len(names) >= 2
    tags = sim.region_tags()
    assert set(np.unique(tags)) <= set(range(len(names)))
    # Rigid bones carry no stress.
    vm = sim.von_mises()
    assert (vm[tags > 0] == 0.0).all()
    assert vm[tags == 0].max() > 0.0
    assert len(sim.obstacles()) == 1


def test_to_meshio_writes_a_file_meshio_reads(tmp_path, beam):
    meshio = pytest.importorskip("meshio")
    beam.step(50)
    mesh = beam.to_meshio()
    path = tmp_path / "beam.vtu"
    meshio.write(path, mesh)
    back = meshio.read(path)
    assert back.points.shape == (beam.n_vertices, 3)
    assert (back.points[:, 2] == 0.0).all()
    assert np.allclose(back.points[:, :2], beam.positions())
    assert np.allclose(back.cell_data["von_mises"][0], beam.von_mises())
    assert back.cells[0].data.shape == (beam.n_triangles, 3)


def test_scene_as_run(beam):
    d = beam.scene_dict()
    assert d["energy"] == "neo-hookean"
    assert "neo-hookean" in beam.scene_toml()
    assert beam.name and beam.dt == pytest.approx(1e-3)
    assert "case-a" in repr(beam)
