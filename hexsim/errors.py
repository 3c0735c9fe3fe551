"""Errors hexsim raises. The CLI turns every :class:`HexsimError` into one line on stderr and exit code 2."""


class HexsimError(Exception):
    """Base class: a refusal with a message that names what is wrong (file, column, row, leg, value)."""


class InputError(HexsimError, ValueError):
    """Bad user input: an option, a scenario file, a parameter value."""


class WorkspaceError(HexsimError, ValueError):
    """A platform pose that needs a leg outside its stroke (names the leg and the length)."""


class PhysicsError(HexsimError, RuntimeError):
    """Invalid physics: a non-finite state or a MuJoCo warning (names the time and, where known, the leg)."""


class ModelNote(UserWarning):
    """Something hexsim changed or approximated in a user's model to drive it (a public MJCF's convention
    brought to hexsim's leg, an actuator replaced): issued with :func:`warnings.warn`; the CLI prints each
    once as ``hexsim: note: …``."""
