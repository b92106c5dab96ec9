"""The exceptions of pyfem2d.

Every error pyfem2d raises derives from :class:`Fem2dError`, and carries the one-line message the
``fem2d`` command line prints for the same input.
"""


class Fem2dError(Exception):
    """Base class of every pyfem2d error."""


class InvalidInputError(Fem2dError, ValueError):
    """A value is wrong: a scene key, an override, an argument, a mesh or model file's content.

    The message names the file (or scene), the field and the value.
    """


class FileError(Fem2dError, OSError):
    """A file (a scene, a mesh, a 3D model) could not be read."""


class StepFailedError(Fem2dError):
    """A step failed: the state became non-finite, ran away, or the solver did not converge.

    The simulation stops there: ``reset()`` or ``restore()`` it to go on.
    """


class InternalError(Fem2dError):
    """A bug in fem2d (a Rust panic, caught before it reached Python)."""


__all__ = [
    "Fem2dError",
    "InvalidInputError",
    "FileError",
    "StepFailedError",
    "InternalError",
]
