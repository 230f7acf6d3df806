"""The estimator contract shared by the package's models: parameters, fitted check, versioned files.

Every estimator takes its hyper-parameters in ``__init__`` (stored under the same names, checked by
one hook, :meth:`Estimator._check_params`), learns in ``fit(X, lengths=None, ...)`` (returning
``self``) into attributes ending with ``_``, and saves to one documented file format. As in
scikit-learn and hmmlearn, ``X`` holds the frames of all sequences concatenated and ``lengths`` their
frame counts (``None``: one sequence). :class:`Estimator` derives ``get_params``, ``set_params`` and
``repr`` from the ``__init__`` signature and owns the parts of ``save`` and ``load`` that every format
shares: a model is written only once fitted, and a file is read only if its ``kind`` and
``format_version`` are ones this estimator reads. Each estimator supplies the format itself
(:meth:`Estimator._write`, :meth:`Estimator._read`, :meth:`Estimator._from_file`).
"""

from __future__ import annotations

import inspect
import os
from abc import ABC, abstractmethod
from collections.abc import Sequence
from pathlib import Path
from typing import Any, ClassVar, TypeVar

import numpy as np

from hoap_actions.errors import DataFileError, InvalidInputError, NotFittedError

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
    """``estimator.get_params()`` ready for a JSON file: numpy scalars as Python ones, a Generator
    ``random_state`` (which no file can hold) as ``None``, and how it reports progress left out."""
    out = {}
    for name, value in estimator.get_params().items():
        if name in estimator._unsaved_params:
            continue
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
    _refit_free_params: ClassVar[tuple[str, ...]] = ()
    """Hyper-parameters a fitted estimator reads after ``fit`` and so takes new values of without a refit."""
    _unsaved_params: ClassVar[tuple[str, ...]] = ()
    """Hyper-parameters that change how ``fit`` reports, not what it learns: files leave them out."""

    @classmethod
    def _param_names(cls) -> list[str]:
        """The ``__init__`` parameters: the hyper-parameters, stored on the instance under the same names."""
        parameters = inspect.signature(cls.__init__).parameters.values()
        return [p.name for p in parameters if p.name != "self" and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]

    def get_params(self) -> dict[str, Any]:
        """Hyper-parameters as given to ``__init__``: ``type(self)(**get_params())`` is an unfitted copy."""
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self: E, **params: Any) -> E:
        """Set hyper-parameters and return ``self``; they are checked together, and on an error none changes.

        An unfitted estimator takes any of its ``__init__`` parameters; a fitted one only those it reads
        after fitting (:attr:`_refit_free_params`): the others would contradict what it learned.
        """
        names = self._param_names()
        unknown = sorted(set(params) - set(names))
        if unknown:
            raise InvalidInputError(f"{type(self).__name__} has no hyper-parameter(s) {unknown}; it has {names}")
        if all(hasattr(self, name) for name in self._learned):
            need_fit = sorted(set(params) - set(self._refit_free_params))
            if need_fit:
                raise InvalidInputError(f"this {type(self).__name__} is fitted: it takes new values of "
                                        f"{list(self._refit_free_params)} only; fit a new one to change {need_fit}")
        previous = self.get_params()
        self.__dict__.update(params)
        try:
            self._check_params()
        except InvalidInputError:
            self.__dict__.update(previous)
            raise
        self._params_changed(set(params))
        return self

    @abstractmethod
    def _check_params(self) -> None:
        """Raise InvalidInputError naming a hyper-parameter that is out of range and what is accepted."""

    def _params_changed(self, names: set[str]) -> None:  # noqa: B027  (a hook: most estimators derive nothing)
        """Forget what was derived from the hyper-parameters ``names`` that :meth:`set_params` changed."""

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
