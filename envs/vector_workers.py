"""Sub-envs in worker processes that take commands and give answers through shared memory, and wait for
each other by busy-waiting a short while before sleeping.

On 2 cores a welded-legs step takes about 0.5 ms; a pipe and a sleeping process cost a sizeable part
of that at every step (the wake-up, the caller's bookkeeping), and in lockstep the two steps then drift
apart (``benchmarks/lockstep_limit.py``: Gymnasium's pipes 1.5x against a busy-waiting exchange's
1.75x, with 1.9x for two envs that never wait). Each command and answer is pickled into the worker's
block of shared memory; a semaphore released once per message makes the exchange correct whatever the
spin does (the reader takes it before reading), the spin only spares it a sleep.
"""

from __future__ import annotations

import multiprocessing as mp
import pickle
import time
from collections.abc import Callable, Sequence
from multiprocessing import shared_memory
from typing import Any

import gymnasium
import numpy as np
from gymnasium.vector.utils import CloudpickleWrapper

from hoap_actions.errors import EnvClosedError, InvalidInputError

__all__ = ["SpinningWorkers", "attribute_value", "step_or_reset"]

BUFFER_BYTES = 16 << 20  # per worker and direction; shared memory is only paid for where written
_HEADER = 32  # int64: asked, answered, command length (negative: a raw action's bytes), answer length
_ALIVE_CHECK_S = 0.1


class SpinningWorkers:
    """One worker process per env made by ``env_fns``, each stepping its env on command. ``spin_s`` is
    how long a side busy-waits for the other's message before sleeping on a semaphore (0: never spin;
    keep it below the time between steps if other work needs the cores then, e.g. a learner's update)."""

    def __init__(self, env_fns: Sequence[Callable[[], gymnasium.Env]], spin_s: float = 0.0005,
                 context: str | None = None) -> None:
        if not (isinstance(spin_s, int | float) and 0.0 <= spin_s < 1.0):
            raise InvalidInputError(f"spin_s={spin_s!r}: the busy-wait must be a number of seconds in [0, 1)")
        self.spin_s = float(spin_s)
        ctx = mp.get_context(context)
        self._links: list[_Link] = []
        try:
            for env_fn in env_fns:
                self._links.append(_Link(ctx, CloudpickleWrapper(env_fn), self.spin_s))
            for link in self._links:
                link.answer()  # the env is built (or its error raised here)
        except BaseException:
            self.close()
            raise

    def send(self, command: str, arguments: Sequence[tuple]) -> None:
        """Ask every worker ``command`` with its own argument tuple; :meth:`gather` collects the answers."""
        for link, args in zip(self._links, arguments, strict=True):
            link.ask((command, args))

    def step(self, actions: np.ndarray) -> None:
        """Ask worker ``i`` to step with ``actions[i]``, sent as raw bytes in the env's action dtype (a step's
        one message that is not pickled); :meth:`gather` collects the answers."""
        for link, action in zip(self._links, actions, strict=True):
            link.ask_step(action)

    def gather(self) -> list[Any]:
        """Each worker's answer to the last :meth:`send`, in order; a worker's error is raised here, after
        every answer is in (so the workers stay in step)."""
        answers = [link.answer_or_error() for link in self._links]
        for answer in answers:
            if isinstance(answer, _Failure):
                raise answer.error
        return answers

    def close(self) -> None:
        for link in self._links:
            link.close()
        self._links = []


def step_or_reset(env: gymnasium.Env, action: np.ndarray, done: bool) -> tuple[tuple, bool]:
    """One sub-env's step as Gymnasium's vector envs make it by default (``AutoresetMode.NEXT_STEP``): after
    an episode ended (``done``), a reset with reward 0 instead of a step; and whether this one ended."""
    if done:
        obs, info = env.reset()
        return (obs, 0.0, False, False, info), False
    result = env.step(action)
    return result, bool(result[2] or result[3])


def attribute_value(env: gymnasium.Env, name: str, args: tuple = (), kwargs: dict | None = None) -> Any:
    """A sub-env's attribute ``name`` (through its wrappers), called with ``args`` if it is a method."""
    attribute = env.get_wrapper_attr(name)
    return attribute(*args, **(kwargs or {})) if callable(attribute) else attribute


class _Failure:
    """An exception raised in a worker, carried back to the caller."""

    def __init__(self, error: BaseException) -> None:
        self.error = error


class _Link:
    """The caller's end of one worker."""

    def __init__(self, ctx: Any, env_fn: CloudpickleWrapper, spin_s: float) -> None:
        self.spin_s = spin_s
        self.memory = shared_memory.SharedMemory(create=True, size=_HEADER + 2 * BUFFER_BYTES)
        self.header = np.ndarray((4,), dtype=np.int64, buffer=self.memory.buf)
        self.header[:] = 0
        self.to_worker, self.to_caller = ctx.Semaphore(0), ctx.Semaphore(0)
        self.asked = 0
        self.process = ctx.Process(target=_serve, args=(env_fn, self.memory.name, self.to_worker, self.to_caller,
                                                        spin_s), daemon=True)
        self.process.start()

    def ask(self, message: tuple) -> None:
        _write(self.memory, _HEADER, 2, self.header, message)
        self._post()

    def ask_step(self, action: np.ndarray) -> None:
        raw = np.ascontiguousarray(action).tobytes()
        self.memory.buf[_HEADER: _HEADER + len(raw)] = raw
        self.header[2] = -len(raw)
        self._post()

    def _post(self) -> None:
        """The message written, tell the worker: the count it waits on, then the semaphore."""
        self.asked += 1
        self.header[0] = self.asked
        self.to_worker.release()

    def answer_or_error(self) -> Any:
        deadline = time.perf_counter() + self.spin_s
        while self.header[1] != self.asked and time.perf_counter() < deadline:
            pass
        while not self.to_caller.acquire(timeout=_ALIVE_CHECK_S):
            if not self.process.is_alive():
                raise EnvClosedError(f"a vector env's worker process ended (exit code {self.process.exitcode}) "
                                     f"before answering; the vector env cannot go on: close it and make another")
        return pickle.loads(self.memory.buf[_HEADER + BUFFER_BYTES: _HEADER + BUFFER_BYTES + int(self.header[3])])

    def answer(self) -> Any:
        answer = self.answer_or_error()
        if isinstance(answer, _Failure):
            raise answer.error
        return answer

    def close(self) -> None:
        try:
            if self.process.is_alive():
                self.ask(("close", ()))
                self.process.join(timeout=5.0)
        finally:
            if self.process.is_alive():
                self.process.terminate()
                self.process.join()
            del self.header
            self.memory.close()
            self.memory.unlink()


def _write(memory: shared_memory.SharedMemory, offset: int, length_slot: int, header: np.ndarray,
           message: Any) -> None:
    payload = pickle.dumps(message, protocol=pickle.HIGHEST_PROTOCOL)
    if len(payload) > BUFFER_BYTES:
        raise InvalidInputError(f"a vector env message of {len(payload)} bytes does not fit its "
                                f"{BUFFER_BYTES}-byte shared buffer; render or return less per call")
    memory.buf[offset: offset + len(payload)] = payload
    header[length_slot] = len(payload)


def _serve(env_fn: CloudpickleWrapper, name: str, to_worker: Any, to_caller: Any, spin_s: float) -> None:
    """A worker's loop: build the env, then answer commands until ``close``; autoreset on the step after
    an episode ends, as Gymnasium's vector envs do by default (``AutoresetMode.NEXT_STEP``)."""
    memory = shared_memory.SharedMemory(name=name)
    header = np.ndarray((4,), dtype=np.int64, buffer=memory.buf)
    answered = 0

    def reply(answer: Any) -> None:
        try:
            _write(memory, _HEADER + BUFFER_BYTES, 3, header, answer)
        except Exception as error:  # an answer too big or not picklable: say so instead
            _write(memory, _HEADER + BUFFER_BYTES, 3, header, _Failure(RuntimeError(repr(error))))
        header[1] = answered
        to_caller.release()

    try:
        env = env_fn()
    except BaseException as error:
        reply(_Failure(error))
        return
    reply(None)
    action_space = env.action_space
    done = False
    while True:
        deadline = time.perf_counter() + spin_s
        while header[0] == answered and time.perf_counter() < deadline:
            pass
        to_worker.acquire()
        answered += 1
        length = int(header[2])
        if length < 0:
            raw = np.frombuffer(memory.buf[_HEADER: _HEADER - length], dtype=action_space.dtype)
            command, args = "step", (raw.reshape(action_space.shape).copy(),)
            del raw  # a view into the memory, which cannot close while one is held
        else:
            command, args = pickle.loads(memory.buf[_HEADER: _HEADER + length])
        if command == "close":
            env.close()
            reply(None)
            break
        try:
            if command == "step":
                answer, done = step_or_reset(env, args[0], done)
            elif command == "reset":
                answer, done = env.reset(**args[0]), False
            elif command == "call":
                answer = attribute_value(env, *args)
            else:
                answer = env.get_wrapper_attr(args[0])
        except Exception as error:
            answer = _Failure(error)
        reply(answer)
    header = None  # the view goes before the memory it looks into
    memory.close()
