"""The estimator contract shared by the package's models: parameters, fitted check, versioned files.

Every estimator takes its hyper-parameters in ``__init__`` (stored under the same names), learns in
``fit`` (returning ``self``) into attributes ending with ``_``, and saves to one documented file
format. :class:`Estimator` derives ``get_params`` and ``repr`` from the ``__init__`` signature, as
scikit-learn does, and owns the parts of ``save`` and ``load`` that every format shares: a model is
written only once fitted, and a file is read only if its ``kind`` and ``format_version`` are ones
this estimator reads. Each estimator supplies the format itself (:meth:`Estimator._write`,
:meth:`Estimator._read`, :meth:`Estimator._from_file`).
"""

from __future__ import annotations

import inspect
import os
from abc import ABC, abstractmethod
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np

from hoap_actions.errors import DataFileError, NotFittedError

__all__ = ["Estimator", "check_is_fitted", "file_params"]

E = TypeVar("E", bound="Estimator")


def check_is_fitted(estimator: Estimator, attributes: str | Sequence[str] | None = None) -> None:
    """Raise NotFittedError unless ``estimator`` has every learned attribute in ``attributes``.

    ``None`` checks the estimator's declared learned attributes (:attr:`Estimator._learned`), which
    both ``fit`` and ``load`` set.
    """
    names = estimator._learned if attributes is None else (attributes,) if isinstance(attributes, str) else attributes
    if not all(hasattr(estimator, name) for name in names):
        name = type(estimator).__name__
        raise NotFittedError(f"this {name} is not fitted yet: call fit() or {name}.load(path) first")


def file_params(estimator: Estimator) -> dict[str, Any]:
    """``estimator.get_params()`` ready for a JSON file: numpy scalars as Python ones, and a Generator
    ``random_state`` (which no file can hold) as ``None``."""
    out = {}
    for name, value in estimator.get_params().items():
        if isinstance(value, np.random.Generator):
            value = None
        out[name] = value.item() if isinstance(value, np.generic) else value
    return out


class Estimator(ABC):
    """Base of the package's estimators: ``get_params``/``repr`` from ``__init__``, save/load through one check.

    Subclasses declare :attr:`_learned` (attributes ``fit`` and ``load`` set), the ``kind`` their
    files carry (:attr:`_file_kind`), the version they write (:attr:`_format_version`) and the
    versions they read (:attr:`_readable_versions`).
    """

    _learned: ClassVar[tuple[str, ...]]
    _file_kind: ClassVar[str]
    _format_version: ClassVar[int]
    _readable_versions: ClassVar[tuple[int, ...]]

    @classmethod
    def _param_names(cls) -> list[str]:
        """The ``__init__`` parameters: the hyper-parameters, stored on the instance under the same names."""
        parameters = inspect.signature(cls.__init__).parameters.values()
        return [p.name for p in parameters if p.name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]

    def get_params(self) -> dict[str, Any]:
        """Hyper-parameters as given to ``__init__``: ``type(self)(**get_params())`` is an unfitted copy."""
        return {name: getattr(self, name) for name in self._param_names()}

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in self.get_params().items())})"

    # -- files

    def save(self, path: str | os.PathLike, overwrite: bool = False) -> None:
        """Write the fitted estimator to exactly ``path`` in its documented, versioned file format.

        An existing file raises DataExistsError unless ``overwrite``; the write goes through
        :func:`hoap_actions.outputs.claimed_file`, so a crash never leaves half a model behind.
        """
        check_is_fitted(self)
        self._write(Path(path), overwrite)

    @classmethod
    def load(cls: type[E], path: str | os.PathLike) -> E:
        """Read an estimator written by :meth:`save`.

        A missing, unreadable or corrupt file, another kind of file, or a format version this release
        does not read raises DataFileError naming ``path``.
        """
        path = Path(path)
        kind, version, contents = cls._read(path)
        if kind != cls._file_kind:
            raise DataFileError(f"{path} is not a {cls._file_kind} file (its kind is {kind!r}); "
                                f"{cls._file_kind}.load reads the files {cls._file_kind}.save writes")
        if isinstance(version, bool) or not isinstance(version, int) or version not in cls._readable_versions:
            raise DataFileError(f"{path} has format_version {version!r}; this version of hoap_actions reads "
                                f"{cls._file_kind} format_versions {cls._readable_versions}")
        model = cls._from_file(path, contents, version)
        check_is_fitted(model)
        return model

    @abstractmethod
    def _write(self, path: Path, overwrite: bool) -> None:
        """Write this fitted estimator's file (called by :meth:`save` once the fitted check passed)."""

    @classmethod
    @abstractmethod
    def _read(cls, path: Path) -> tuple[Any, Any, Any]:
        """``(kind, format_version, contents)`` of the file at ``path``, as Python values (None if absent)."""

    @classmethod
    @abstractmethod
    def _from_file(cls: type[E], path: Path, contents: Any, version: int) -> E:
        """The estimator held in ``contents`` (of a readable kind and version), or DataFileError naming ``path``."""
