"""The mesh pipeline from Python: a model file or arrays of a 3D surface to a 2D FEM mesh."""

import math

import numpy as np
import pytest

import pyfem2d


def ellipsoid(a=0.3, b=1.0, c=0.2, n_u=48, n_v=24):
    """A closed UV ellipsoid surface: semi-axes a (x), b (y), c (z)."""
    pts = [(0.0, b, 0.0)]
    for i in range(1, n_v):
        th = math.pi * i / n_v
        for j in range(n_u):
            ph = 2 * math.pi * j / n_u
            pts.append((a * math.sin(th) * math.cos(ph), b * math.cos(th), c * math.sin(th) * math.sin(ph)))
    pts.append((0.0, -b, 0.0))
    tris = []
    ring = lambda i, j: 1 + (i - 1) * n_u + (j % n_u)
    for j in range(n_u):
        tris.append((0, ring(1, j), ring(1, j + 1)))
    for i in range(1, n_v - 1):
        for j in range(n_u):
            tris.append((ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)))
            tris.append((ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)))
    last = len(pts) - 1
    for j in range(n_u):
        tris.append((ring(n_v - 1, j), last, ring(n_v - 1, j + 1)))
    return pts, tris


def test_a_point_cloud_held_in_python_becomes_a_quality_mesh():
    pts, tris = ellipsoid()
    # Lists (any array-like) are accepted and converted once.
    mesh = pyfem2d.mesh_model(points=pts, triangles=tris, view="side", max_area=2e-3)
    p, t = mesh["points"], mesh["triangles"]
    assert p.shape[1] == 2 and t.shape[1] == 3 and t.dtype == np.int64
    q = mesh["quality"]
    assert q["triangles"] == len(t) and q["vertices"] == len(p)
    assert q["non_positive_triangles"] == 0
    assert q["min_angle_deg"] >= 20.0
    # The side view (image (z, y)) of the ellipsoid is an ellipse of semi-axes c and b.
    # The alpha shape covers the ellipse; simplification (tolerance epsilon, a quarter of the
    # alpha radius) cuts chords off the outline: about 5 % of the area here, within epsilon.
    assert q["polygon_area"] == pytest.approx(math.pi * 0.2 * 1.0, rel=0.01)
    assert q["mesh_area"] == pytest.approx(q["polygon_area"], rel=0.06)
    assert q["boundary_hausdorff"] <= 1.01 * mesh["epsilon"]
    assert (mesh["regions"] == 0).all()


def test_a_model_file_meshes_as_the_arrays_do(tmp_path):
    pts, tris = ellipsoid()
    obj = tmp_path / "ellipsoid.obj"
    lines = [f"v {x} {y} {z}" for x, y, z in pts] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in tris]
    obj.write_text("\n".join(lines) + "\n")
    from_file = pyfem2d.mesh_model(str(obj), max_area=2e-3)
    from_arrays = pyfem2d.mesh_model(points=np.array(pts), triangles=np.array(tris), max_area=2e-3)
    assert np.array_equal(from_file["points"], from_arrays["points"])
    assert np.array_equal(from_file["triangles"], from_arrays["triangles"])


def test_a_python_mesh_is_simulated():
    pts, tris = ellipsoid()
    mesh = pyfem2d.mesh_model(points=pts, triangles=tris, max_area=4e-3)
    text = pyfem2d.mesh_json(mesh["points"], mesh["triangles"])
    scene = """
name = "python-mesh"
energy = "neo-hookean"
gravity = [0.0, -9.8]
[mesh]
kind = "file"
path = "ellipse.json"
[material]
youngs_modulus = 5e4
poisson_ratio = 0.3
density = 1000.0
[solver]
kind = "implicit"
dt = 0.01
steps = 20
[[pinned]]
min = [-1.0, 0.9]
max = [1.0, 1.1]
"""
    sim = pyfem2d.Simulation.from_toml(scene, files={"ellipse.json": text})
    assert sim.n_triangles == len(mesh["triangles"])
    sim.run()
    u = sim.displacements()
    assert np.isfinite(u).all()
    # Hung from its top, the body sags.
    assert u[:, 1].min() < 0.0
