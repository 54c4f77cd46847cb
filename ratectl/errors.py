"""Errors raised by ratectl.

Every error derives from `RatectlError`. Messages say what was wrong and
what is allowed; the objects carry the numbers behind the message as attributes
so that a program can react without parsing text.
"""

from __future__ import annotations

__all__ = [
    "RatectlError",
    "ModelError",
    "InputError",
    "SingularityError",
    "SolverError",
    "ImportModelError",
    "DriverError",
]


class RatectlError(Exception):
    """Base class of every error raised by ratectl."""


class ModelError(RatectlError, ValueError):
    """A robot model is ill-formed: a bad DH entry, joint kind, limit or transform.

    Attributes:
        field: the name of the offending field (``"d"``, ``"qlim"``, ...), or None.
        joint: the 0-based index of the offending joint, or None.
        value: the offending value, or None.
    """

    def __init__(self, message: str, *, field: str | None = None,
                 joint: int | None = None, value: object = None) -> None:
        super().__init__(message)
        self.field = field
        self.joint = joint
        self.value = value


class InputError(RatectlError, ValueError):
    """An argument to a function is wrong: shape, finiteness, or an unknown option.

    Attributes:
        argument: the name of the offending argument.
        value: the offending value (may be an array).
    """

    def __init__(self, message: str, *, argument: str | None = None,
                 value: object = None) -> None:
        super().__init__(message)
        self.argument = argument
        self.value = value


class SingularityError(RatectlError, ArithmeticError):
    """A computation needs a regular Jacobian and the Jacobian is singular.

    Attributes:
        sigma_min: the smallest singular value of the Jacobian.
        tolerance: the tolerance it was compared against.
    """

    def __init__(self, message: str, *, sigma_min: float, tolerance: float) -> None:
        super().__init__(message)
        self.sigma_min = float(sigma_min)
        self.tolerance = float(tolerance)


class SolverError(RatectlError, RuntimeError):
    """A numerical solver (e.g. the QP) failed.

    Attributes:
        status: the solver's own status text or code.
        problem: the problem data that failed (a dict of arrays), for reproduction.
    """

    def __init__(self, message: str, *, status: object = None,
                 problem: dict | None = None) -> None:
        super().__init__(message)
        self.status = status
        self.problem = problem


class ImportModelError(ModelError):
    """A URDF or MJCF file cannot be turned into a chain.

    Attributes:
        element: a description of the element at fault (tag and name).
    """

    def __init__(self, message: str, *, element: str | None = None) -> None:
        super().__init__(message, field=element)
        self.element = element


class DriverError(RatectlError, RuntimeError):
    """A robot interface (a `ratectl.drivers` driver) failed: it cannot connect, the
    robot refused a command, or the connection was lost.

    Attributes:
        driver: the driver's class name.
        cause: the underlying exception of the robot's own library (also ``__cause__``), or None.
    """

    def __init__(self, message: str, *, driver: str | None = None,
                 cause: BaseException | None = None) -> None:
        super().__init__(message)
        self.driver = driver
        self.cause = cause
