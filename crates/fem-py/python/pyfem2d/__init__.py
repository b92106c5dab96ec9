"""pyfem2d: 2D energy-based finite element elastodynamics (fem2d) from Python.

The same soft body under several elastic energies (StVK, co-rotational, Neo-Hookean, stable
Neo-Hookean, linear) and several time-stepping frameworks (explicit FEM, PBD, XPBD, implicit
Euler, VBD, Projective Dynamics, quasi-Newton, linearly implicit Euler, static), with numpy
arrays in and out. A thin layer over the Rust crates of fem2d: scenes, solver names and error
messages are the ``fem2d`` command line's.

    >>> import pyfem2d
    >>> sim = pyfem2d.Simulation("case-a", energy="neo-hookean")
    >>> sim.step(100)                     # doctest: +ELLIPSIS
    StepReport(...)
    >>> x = sim.positions()               # (n, 2) float64, m

See docs/python.md in the repository for the whole API.
"""

from ._errors import (
    Fem2dError,
    FileError,
    InternalError,
    InvalidInputError,
    StepFailedError,
)
from ._native import (
    Simulation,
    Snapshot,
    StepReport,
    __version__,
    budget,
    case_text,
    cases,
    energies,
    mesh_json,
    mesh_model,
    run,
    solvers,
    table1,
)

__all__ = [
    "Fem2dError",
    "FileError",
    "InternalError",
    "InvalidInputError",
    "Simulation",
    "Snapshot",
    "StepFailedError",
    "StepReport",
    "__version__",
    "budget",
    "case_text",
    "cases",
    "energies",
    "mesh_json",
    "mesh_model",
    "run",
    "solvers",
    "table1",
]
