"""The project's exceptions: one small hierarchy, each message says what was wrong and what is accepted.

Every class also derives from the built-in a caller would naturally catch (``ValueError`` for bad
values, ``FileNotFoundError`` for missing files, ...), so generic ``except ValueError`` code keeps working.
"""

from __future__ import annotations


class HoapActionsError(Exception):
    """Base class of every error raised on purpose by hoap_actions."""


class InvalidInputError(HoapActionsError, ValueError):
    """A value has the wrong shape, dtype, range, or is NaN/inf."""


class NotFittedError(HoapActionsError, AttributeError):
    """An estimator was used before ``fit`` (or ``load``) gave it its learned attributes."""


class IdentifiabilityError(InvalidInputError):
    """The training data cannot determine the model's parameters (e.g. effects that do not span R^p)."""


class DataFileError(HoapActionsError, OSError):
    """A dataset or model file is missing, truncated, corrupt or of an unsupported format version."""


class DataExistsError(HoapActionsError, FileExistsError):
    """Writing would overwrite an existing dataset or model file; pass ``overwrite=True`` to allow it."""


class EnvClosedError(HoapActionsError, RuntimeError):
    """An environment (or its simulator) was used after ``close()``."""


class ResetNeededError(HoapActionsError, RuntimeError):
    """An environment was stepped before a reset finished (never reset, or its last reset was interrupted)."""


class EnvCopyError(HoapActionsError, TypeError):
    """An environment was copied or pickled: it owns a physics client that a copy cannot share."""


class OutputPathError(HoapActionsError, OSError):
    """An output cannot be written where asked (a folder that cannot be created, no write permission)."""


class DisplayUnavailableError(HoapActionsError, RuntimeError):
    """``render_mode="human"`` cannot open a window here (no display, no OpenGL, or one is open already)."""


class ExtrapolationWarning(UserWarning):
    """A model was asked far outside the range it was trained on; its answer is an unchecked extrapolation."""


class UnseenDemonstratorWarning(UserWarning):
    """A recording's demonstrator is none of those the models learned from: expect lower figures."""


class MissingModelPartWarning(UserWarning):
    """Models from an older or leaner fit lack a part a task can use; it runs without it, less well."""
