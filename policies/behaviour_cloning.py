"""Behaviour cloning: a small MLP regressed from the state observation onto a demonstrator's actions.

The learning baseline a robot-learning reader tries first against the PHMM policy: no model of the
task, no perception, no phases; the network maps what the env observes now to what the demonstrator
(e.g. the scripted expert, collected as a Minari dataset by ``hoap-actions collect``) did then.
Its input is the goal-env observation flattened (:func:`state_vector`: ``observation`` then
``desired_goal``), standardised with the training data's mean and spread.

:class:`BehaviourCloning` is the estimator (``fit(observations, actions)``, ``predict``, versioned
``save``/``load``); :class:`BehaviourCloningPolicy` acts with a fitted one in any ``env.step`` loop
(registered as ``"bc"`` in :data:`~hoap_actions.policies.registry.POLICIES`);
:func:`minari_transitions` reads the (observation, action) pairs of Minari datasets.

PyTorch is an optional dependency, imported only when a network is built or read:
``pip install "hoap-actions[rl]"``.
"""

from __future__ import annotations

import collections
import contextlib
import io
import json
import logging
import os
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np

from hoap_actions.envs import ENV_IDS
from hoap_actions.errors import DataFileError, InvalidInputError
from hoap_actions.inputs import checked_input_file
from hoap_actions.outputs import claimed_file, write_bytes
from hoap_actions.primitives.base import Estimator, check_is_fitted, file_params

__all__ = ["BehaviourCloning", "BehaviourCloningPolicy", "minari_transitions", "state_vector"]

logger = logging.getLogger(__name__)

FORMAT_VERSION = 1
STD_FLOOR = 1e-3
"""Smallest spread an input is divided by in standardisation: inputs that barely vary in the
demonstrations (the welded robot's leg joints, its base pose) are centred, not blown up."""
MAX_FILE_BYTES = 256 * 2**20
SCHEDULES = ("constant", "cosine")
STALL_CHANGE = 1e-4
"""Largest per-step change (m, rad, rad/s) of every number of the observation for which the policy
counts the robot as standing still (stuck against a limit it measured 0.3-5e-5; moving, 1e-3 and more)."""


def _torch():
    """PyTorch, or an error saying how to install it."""
    try:
        import torch
    except ImportError:
        raise InvalidInputError('behaviour cloning needs PyTorch: pip install "hoap-actions[rl]" (or [bench])'
                                ) from None
    return torch


@contextlib.contextmanager
def _torch_settings(torch: Any, threads: int, deterministic: bool = False) -> Iterator[None]:
    """``threads`` intra-op threads (and deterministic algorithms) for the duration, as they were after."""
    before = torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()
    torch.set_num_threads(threads)
    if deterministic:
        torch.use_deterministic_algorithms(True)
    try:
        yield
    finally:
        torch.set_num_threads(before[0])
        torch.use_deterministic_algorithms(before[1])


def _network(torch: Any, n_inputs: int, hidden: Sequence[int], n_outputs: int) -> Any:
    """The MLP: ReLU layers of widths ``hidden``, then a linear output."""
    layers: list[Any] = []
    width = n_inputs
    for size in hidden:
        layers += [torch.nn.Linear(width, size), torch.nn.ReLU()]
        width = size
    layers.append(torch.nn.Linear(width, n_outputs))
    return torch.nn.Sequential(*layers)


def state_vector(obs: dict[str, np.ndarray]) -> np.ndarray:
    """The goal-env observation flattened for a network: ``observation`` then ``desired_goal`` on the
    last axis (one observation ``(D,)``, or a batch ``(T, D)`` as Minari episodes hold them)."""
    try:
        parts = [np.asarray(obs["observation"], dtype=np.float64), np.asarray(obs["desired_goal"], dtype=np.float64)]
    except (KeyError, TypeError, IndexError):
        raise InvalidInputError("a state observation is a goal-env dict with 'observation' and 'desired_goal'; got "
                                f"{type(obs).__name__}") from None
    return np.concatenate(parts, axis=-1)


def minari_transitions(datasets: Sequence[Any], episodes: int | None = None
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(observations (N, D), actions (N, A), lengths)`` of the first ``episodes`` episodes (all if
    None) of Minari ``datasets`` (ids, read from Minari's datasets folder, or loaded datasets), in
    order: each episode's observations but the last (:func:`state_vector`) beside the actions taken."""
    try:
        import minari
    except ImportError:
        raise InvalidInputError('reading Minari datasets needs Minari: pip install "hoap-actions[minari]"') from None
    observations, actions, lengths = [], [], []
    for dataset in datasets:
        if isinstance(dataset, str):
            dataset = minari.load_dataset(dataset)
        for episode in dataset.iterate_episodes():
            if episodes is not None and len(lengths) >= episodes:
                break
            observations.append(state_vector(episode.observations)[:-1])
            actions.append(np.asarray(episode.actions, dtype=np.float64))
            lengths.append(len(episode.actions))
    if episodes is not None and len(lengths) < episodes:
        raise InvalidInputError(f"asked for {episodes} episodes; the datasets hold {len(lengths)}")
    if not lengths:
        raise InvalidInputError("the datasets hold no episodes")
    return np.concatenate(observations), np.concatenate(actions), np.array(lengths)


class BehaviourCloning(Estimator):
    """An MLP fitted by mean-squared error from observations to actions (module docstring).

    Parameters
    ----------
    hidden:
        Widths of the hidden ReLU layers.
    epochs:
        Passes over the training pairs.
    batch_size:
        Pairs per Adam step.
    learning_rate, weight_decay:
        Adam's step size and L2 penalty.
    schedule:
        ``"constant"`` step size, or ``"cosine"``: decayed from ``learning_rate`` to 0 over the
        epochs along half a cosine (fewer epochs reach a lower loss).
    normalise:
        Standardise each input with the training mean and spread (at least :data:`STD_FLOOR`);
        False: inputs as they are.
    chunk:
        Actions predicted per observation: this step's and the next ``chunk - 1`` of the same
        episode (its last action repeated past its end). :class:`BehaviourCloningPolicy` acts with
        the mean of the predictions made for the current step (temporal ensembling, as ACT does).
    random_state:
        Seed (int) of the initial weights and the order of the mini-batches: the same seed gives the
        same weights bit for bit on a CPU with the same ``threads``.
    threads:
        PyTorch threads while fitting (restored after).

    Attributes (after ``fit`` or ``load``)
    --------------------------------------
    network_:
        The fitted ``torch.nn.Sequential``, on standardised inputs; ``chunk`` actions per input.
    input_mean_, input_scale_:
        ``(D,)`` float32: what inputs are standardised with (0 and 1 when ``normalise`` is False).
    loss_curve_:
        Mean training loss of each epoch.

    Saved (:meth:`save`) as one file written by ``torch.save``: ``{"header": JSON text, "state_dict":
    tensors}``; the header holds ``kind`` "BehaviourCloning", ``format_version``
    :data:`FORMAT_VERSION`, ``params`` (as :meth:`get_params`), ``n_inputs``, ``n_outputs`` (the
    action's length) and ``loss_curve``; the tensors are the network's and ``input_mean`` / ``input_scale``. It is read
    with ``weights_only=True`` (no code runs) and checked against the header before use.
    """

    _learned = ("network_", "input_mean_", "input_scale_", "loss_curve_")
    _file_kind = "BehaviourCloning"
    _format_version = FORMAT_VERSION
    _readable_versions = (FORMAT_VERSION,)

    def __init__(self, hidden: Sequence[int] = (256, 256), epochs: int = 30, batch_size: int = 256,
                 learning_rate: float = 1e-3, weight_decay: float = 0.0, schedule: str = "constant",
                 normalise: bool = True, chunk: int = 1, random_state: int = 0, threads: int = 1) -> None:
        self.hidden = hidden
        self.epochs = epochs
        self.batch_size = batch_size
        self.learning_rate = learning_rate
        self.weight_decay = weight_decay
        self.schedule = schedule
        self.normalise = normalise
        self.chunk = chunk
        self.random_state = random_state
        self.threads = threads

    def _check_params(self) -> None:
        def positive_int(value: object) -> bool:
            return isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value > 0

        if isinstance(self.hidden, (str, bytes)) or not isinstance(self.hidden, Sequence) or not all(
                positive_int(h) for h in self.hidden):
            raise InvalidInputError(f"hidden must be a sequence of positive ints (layer widths); got {self.hidden!r}")
        for name in ("epochs", "batch_size", "chunk", "threads"):
            if not positive_int(getattr(self, name)):
                raise InvalidInputError(f"{name} must be a positive int; got {getattr(self, name)!r}")
        for name, value, accepted in (("learning_rate", self.learning_rate, "> 0"),
                                      ("weight_decay", self.weight_decay, ">= 0")):
            number = not isinstance(value, bool) and isinstance(value, (int, float, np.number)) and np.isfinite(value)
            if not number or value < 0 or (value == 0 and accepted == "> 0"):
                raise InvalidInputError(f"{name} must be a finite number {accepted}; got {value!r}")
        if self.schedule not in SCHEDULES:
            raise InvalidInputError(f"schedule must be one of {SCHEDULES}; got {self.schedule!r}")
        if not isinstance(self.normalise, bool):
            raise InvalidInputError(f"normalise must be True or False; got {self.normalise!r}")
        if isinstance(self.random_state, bool) or not isinstance(self.random_state, (int, np.integer)) or not (
                0 <= self.random_state < 2**63):
            raise InvalidInputError(f"random_state must be an int seed in 0..2**63-1; got {self.random_state!r}")

    # -- fit and predict

    def fit(self, observations: np.ndarray, actions: np.ndarray, lengths: Sequence[int] | None = None
            ) -> BehaviourCloning:
        """Fit the network to ``actions`` ``(N, A)`` taken at ``observations`` ``(N, D)`` in episodes of
        ``lengths`` steps (None: one episode), e.g. from :func:`minari_transitions`; returns ``self``."""
        self._check_params()
        X = _finite_2d(observations, "observations")
        Y = _finite_2d(actions, "actions")
        if len(X) != len(Y):
            raise InvalidInputError(f"observations has {len(X)} rows and actions {len(Y)}; give one action per "
                                    "observation")
        Y = _chunks(Y, _episode_ends(lengths, len(Y)), self.chunk)
        torch = _torch()
        if self.normalise:
            mean, scale = X.mean(axis=0), np.maximum(X.std(axis=0), STD_FLOOR)
        else:
            mean, scale = np.zeros(X.shape[1]), np.ones(X.shape[1])
        inputs = torch.from_numpy(((X - mean) / scale).astype(np.float32))
        targets = torch.from_numpy(Y.astype(np.float32))
        with _torch_settings(torch, self.threads, deterministic=True), torch.random.fork_rng(devices=[]):
            torch.manual_seed(int(self.random_state))
            network = _network(torch, X.shape[1], self.hidden, Y.shape[1])
            order = torch.Generator().manual_seed(int(self.random_state))
            optimiser = torch.optim.Adam(network.parameters(), lr=self.learning_rate, weight_decay=self.weight_decay)
            steps = self.epochs * -(-len(X) // self.batch_size)
            decay = torch.optim.lr_scheduler.LambdaLR(
                optimiser, lambda step: 0.5 * (1 + np.cos(np.pi * step / steps)) if self.schedule == "cosine" else 1.0)
            losses = []
            for epoch in range(self.epochs):
                total = 0.0
                for batch in torch.randperm(len(X), generator=order).split(self.batch_size):
                    loss = torch.nn.functional.mse_loss(network(inputs[batch]), targets[batch])
                    optimiser.zero_grad()
                    loss.backward()
                    optimiser.step()
                    decay.step()
                    total += float(loss.detach()) * len(batch)
                losses.append(total / len(X))
                logger.debug("epoch %d: training loss %.5f", epoch + 1, losses[-1])
        network.eval()
        self.network_ = network
        self.input_mean_, self.input_scale_ = mean.astype(np.float32), scale.astype(np.float32)
        self.loss_curve_ = losses
        logger.info("fitted behaviour cloning on %d pairs: final training loss %.5f", len(X), losses[-1])
        return self

    def predict(self, observations: np.ndarray) -> np.ndarray:
        """Actions ``(N, A)`` for observations ``(N, D)`` (float32, as the network computes them): the
        first of each chunk (:meth:`predict_chunks`)."""
        return self.predict_chunks(observations)[:, 0]

    def predict_chunks(self, observations: np.ndarray) -> np.ndarray:
        """Actions ``(N, chunk, A)``: for each observation, its step's and the next ``chunk - 1``."""
        check_is_fitted(self)
        X = _finite_2d(observations, "observations")
        if X.shape[1] != len(self.input_mean_):
            raise InvalidInputError(f"observations have {X.shape[1]} columns; this model takes {len(self.input_mean_)}")
        torch = _torch()
        inputs = torch.from_numpy(((X - self.input_mean_) / self.input_scale_).astype(np.float32))
        with torch.inference_mode():
            return self.network_(inputs).numpy().reshape(len(X), self.chunk, -1)

    @property
    def n_inputs_(self) -> int:
        """Length of the observation vector the model takes."""
        check_is_fitted(self)
        return len(self.input_mean_)

    @property
    def n_outputs_(self) -> int:
        """Length of the action it gives."""
        check_is_fitted(self)
        return int(self.network_[-1].out_features) // self.chunk

    # -- files

    def _write(self, path: Path, overwrite: bool) -> None:
        torch = _torch()
        header = {"kind": self._file_kind, "format_version": self._format_version, "params": file_params(self),
                  "n_inputs": self.n_inputs_, "n_outputs": self.n_outputs_, "loss_curve": self.loss_curve_}
        header["params"]["hidden"] = list(self.hidden)
        tensors = {"input_mean": torch.from_numpy(self.input_mean_), "input_scale": torch.from_numpy(self.input_scale_),
                   **{f"network.{k}": v for k, v in self.network_.state_dict().items()}}
        buffer = io.BytesIO()
        torch.save({"header": json.dumps(header), "state_dict": tensors}, buffer)
        with claimed_file(path, overwrite, what=f"{self._file_kind} file") as partial:
            write_bytes(partial, buffer.getvalue(), f"{self._file_kind} file")

    @classmethod
    def _read(cls, path: Path) -> tuple[Any, Any, Any]:
        torch = _torch()
        path = checked_input_file(path, f"{cls._file_kind} file", MAX_FILE_BYTES)
        try:
            document = torch.load(path, map_location="cpu", weights_only=True)
            header = json.loads(document["header"])
            tensors = document["state_dict"]
        except Exception as exc:  # torch.load raises many kinds for a file it cannot read
            raise DataFileError(f"{path} is not a readable {cls._file_kind} file (torch.save of a header and "
                                f"tensors): {type(exc).__name__}: {exc}") from None
        if not isinstance(header, dict) or not isinstance(tensors, dict):
            raise DataFileError(f"{path} is not a {cls._file_kind} file: no header object and tensors")
        return header.get("kind"), header.get("format_version"), (header, tensors)

    @classmethod
    def _from_file(cls, path: Path, contents: Any, version: int) -> BehaviourCloning:
        header, tensors = contents
        torch = _torch()
        try:
            params = dict(header["params"])
            params["hidden"] = tuple(params["hidden"])
            model = cls(**params)
            model._check_params()
            n_inputs, n_outputs = int(header["n_inputs"]), int(header["n_outputs"])
            loss_curve = [float(v) for v in header["loss_curve"]]
        except (KeyError, TypeError, ValueError) as exc:
            raise DataFileError(f"{path}: its header is not a {cls._file_kind} header ({exc})") from None
        network = _network(torch, n_inputs, model.hidden, n_outputs * model.chunk)
        expected = {"input_mean": (n_inputs,), "input_scale": (n_inputs,),
                    **{f"network.{k}": tuple(v.shape) for k, v in network.state_dict().items()}}
        found = {k: tuple(v.shape) if isinstance(v, torch.Tensor) else None for k, v in tensors.items()}
        if found != expected:
            raise DataFileError(f"{path}: its tensors {found} do not match the network its header describes "
                                f"{expected}")
        if not all(v.dtype == torch.float32 and bool(torch.isfinite(v).all()) for v in tensors.values()):
            raise DataFileError(f"{path}: its tensors must be finite float32")
        if not bool((tensors["input_scale"] > 0).all()):
            raise DataFileError(f"{path}: its input_scale must be positive")
        network.load_state_dict({k.removeprefix("network."): v for k, v in tensors.items() if k.startswith("network.")})
        network.eval()
        model.network_ = network
        model.input_mean_ = tensors["input_mean"].numpy().copy()
        model.input_scale_ = tensors["input_scale"].numpy().copy()
        model.loss_curve_ = loss_curve
        return model


def _episode_ends(lengths: Sequence[int] | None, n: int) -> np.ndarray:
    """For each of ``n`` rows, the index one past the last row of its episode."""
    if lengths is None:
        return np.full(n, n)
    sizes = np.asarray(lengths)
    if sizes.ndim != 1 or not np.issubdtype(sizes.dtype, np.integer) or np.any(sizes < 1) or sizes.sum() != n:
        raise InvalidInputError(f"lengths must be positive ints summing to the {n} rows; got {lengths!r}")
    return np.repeat(np.cumsum(sizes), sizes)


def _chunks(actions: np.ndarray, ends: np.ndarray, chunk: int) -> np.ndarray:
    """``(N, chunk * A)``: each row's action and the next ``chunk - 1`` of its episode, the last repeated."""
    rows = np.minimum(np.arange(len(actions))[:, None] + np.arange(chunk), ends[:, None] - 1)
    return actions[rows].reshape(len(actions), -1)


def _finite_2d(values: np.ndarray, name: str) -> np.ndarray:
    array = np.asarray(values, dtype=np.float64)
    if array.ndim != 2 or array.shape[0] == 0 or array.shape[1] == 0:
        raise InvalidInputError(f"{name} must be a non-empty 2-D array (rows, columns); got shape {array.shape}")
    if not np.isfinite(array).all():
        raise InvalidInputError(f"{name} holds NaN or inf; give finite values")
    return array


class BehaviourCloningPolicy:
    """``obs -> action`` from a fitted :class:`BehaviourCloning` model, clipped to the env's action space.

    Parameters
    ----------
    env
        an env whose observations and actions have the sizes the model was fitted on, made with
        ``control_mode="ee_delta"`` (the scripted expert's, whose episodes it is fitted on).
    model
        a fitted :class:`BehaviourCloning` or the path of a saved one. With ``chunk`` > 1, the action
        is the mean of what the last ``chunk`` predictions said for this step.
    patience
        give up (``failure`` "stalled") once the observation has stayed still, no number of it changing
        by more than :data:`STALL_CHANGE` per step, for this many steps in a row: the network then
        sees the same input and gives the same action, and the robot stays where it is (an episode
        would run out its time). None: never give up.
    threads
        PyTorch threads of this process (set here, process-wide: one per worker process keeps the
        processes of a sweep from competing for cores).
    """

    failure: str | None = None
    control_mode = "ee_delta"
    env_ids = ENV_IDS

    def __init__(self, env: gymnasium.Env, model: BehaviourCloning | str | os.PathLike, patience: int | None = None,
                 threads: int = 1) -> None:
        if not isinstance(model, BehaviourCloning):
            model = BehaviourCloning.load(model)
        check_is_fitted(model)
        space = env.observation_space
        size = sum(int(np.prod(space[k].shape)) for k in ("observation", "desired_goal"))
        if size != model.n_inputs_ or env.action_space.shape != (model.n_outputs_,):
            raise InvalidInputError(f"the model maps {model.n_inputs_} inputs to {model.n_outputs_} actions; this env "
                                    f"observes {size} and takes actions of shape {env.action_space.shape}")
        if patience is not None and (isinstance(patience, bool) or not isinstance(patience, int) or patience < 1):
            raise InvalidInputError(f"patience must be None or a positive int (steps); got {patience!r}")
        _torch().set_num_threads(threads)
        self.model = model
        self.patience = patience
        self.low, self.high = env.action_space.low, env.action_space.high
        self._made: collections.deque[np.ndarray] = collections.deque(maxlen=model.chunk)

    def reset(self, obs: dict[str, np.ndarray], info: dict[str, Any]) -> None:
        """A new episode: the stall count and the chunks predicted so far start again."""
        self.failure = None
        self._last = state_vector(obs)
        self._still = 0
        self._made.clear()

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        state = state_vector(obs)
        self._still = self._still + 1 if np.max(np.abs(state - self._last)) < STALL_CHANGE else 0
        self._last = state
        if self.patience is not None and self._still >= self.patience:
            self.failure = "stalled"
        self._made.appendleft(self.model.predict_chunks(state[None])[0])
        action = np.mean([chunk[age] for age, chunk in enumerate(self._made)], axis=0)
        return np.clip(action, self.low, self.high).astype(np.float32)
