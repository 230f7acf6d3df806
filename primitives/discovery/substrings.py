"""Substring search on state strings: longest common substrings and the primitives they cut (Fig. 5)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hoap_actions.errors import InvalidInputError

__all__ = ["MIN_COMMON_LENGTH", "find_primitives", "longest_common_substring"]

MIN_COMMON_LENGTH = 2  # states: a shared substring shorter than this is not a primitive of its own


def longest_common_substring(a: Sequence[int], b: Sequence[int]) -> tuple[int, int, int]:
    """Longest common substring of two int strings by dynamic programming, one numpy row per symbol of ``a``.

    Returns ``(start_in_a, start_in_b, length)``; the first longest in row-major order; length 0 if none.
    """
    end_a, end_b, length = _longest_match(np.asarray(a, int), np.asarray(b, int))
    return end_a - length + 1, end_b - length + 1, length


def _longest_match(x: np.ndarray, y: np.ndarray) -> tuple[int, int, int]:
    """``(end_x, end_y, length)`` of the longest common substring.

    ``run[j]`` is the length of the common suffix of ``x[:i+1]`` and ``y[:j+1]``; each row is one
    vector operation on the previous row shifted by one.
    """
    run = np.zeros(len(y) + 1, dtype=np.int64)
    best = (0, 0, 0)
    for i, symbol in enumerate(x):
        new = np.zeros_like(run)
        new[1:] = np.where(y == symbol, run[:-1] + 1, 0)
        run = new
        j = int(np.argmax(run[1:])) if len(y) else 0
        if len(y) and run[j + 1] > best[2]:
            best = (i, j, int(run[j + 1]))
    return best


def find_primitives(
    sequences: Sequence[Sequence[int]], min_length: int = MIN_COMMON_LENGTH
) -> tuple[list[tuple[int, ...]], list[list[int]]]:
    """Cut state strings into common and unique substrings (the paper's LCS step, Fig. 5).

    Procedure, generalising the two-string example to many strings: keep every string as a list of
    pieces (initially one piece each). Repeatedly take the distinct pieces, find the longest
    substring of length >= ``min_length`` common to two different ones (the first such in order of
    appearance), and split every piece at every (non-overlapping, left to right) occurrence of it.
    Stop when no two distinct pieces share such a substring; the distinct pieces are then the
    primitives, each either common or unique to one string.

    Pieces found earlier are split again when a later, shorter common substring lies inside them;
    extracting only from the matched pair would make the push of Fig. 7 over the longest distance
    one primitive (P1 P2 P3) instead of reusing the shorter pushes' P1 and P2. Each round splits at
    least one piece, so it ends after at most as many rounds as there are symbols.

    Returns ``(primitives, labels)``: primitives as tuples in order of first appearance, and per
    string the primitive indices of its pieces in order.
    """
    if min_length < 1:
        raise InvalidInputError(f"min_length must be >= 1, got {min_length}")
    pieces = [[tuple(int(s) for s in seq)] if len(seq) else [] for seq in sequences]
    while True:
        distinct = list(dict.fromkeys(p for seq in pieces for p in seq))
        common = _longest_common_piece(distinct)
        if len(common) < min_length:
            break
        pieces = [[part for piece in seq for part in _split_at(piece, common)] for seq in pieces]
    primitives = list(dict.fromkeys(p for seq in pieces for p in seq))
    index = {p: k for k, p in enumerate(primitives)}
    return primitives, [[index[p] for p in seq] for seq in pieces]


def _longest_common_piece(pieces: list[tuple[int, ...]]) -> tuple[int, ...]:
    """Longest substring shared by two different pieces (empty tuple if none); of those, the first in order.

    A binary search on the length: a common substring of length n has common prefixes of every
    shorter length, and each test hashes the O(total length) substrings of one length. The
    pairwise dynamic programme it replaces was quadratic in the total length, every round.
    """
    low, high = 0, max((len(p) for p in pieces), default=0)
    while low < high:
        middle = (low + high + 1) // 2
        if _first_shared(pieces, middle):
            low = middle
        else:
            high = middle - 1
    return _first_shared(pieces, low) if low else ()


def _first_shared(pieces: list[tuple[int, ...]], n: int) -> tuple[int, ...]:
    """The first (in piece order, then position) length-``n`` substring found in two different pieces, or ``()``."""
    owner: dict[tuple[int, ...], int] = {}
    shared = set()
    for k, piece in enumerate(pieces):
        for i in range(len(piece) - n + 1):
            sub = piece[i : i + n]
            if owner.setdefault(sub, k) != k:
                shared.add(sub)
    if shared:
        for piece in pieces:
            for i in range(len(piece) - n + 1):
                if piece[i : i + n] in shared:
                    return piece[i : i + n]
    return ()


def _split_at(piece: tuple[int, ...], sub: tuple[int, ...]) -> list[tuple[int, ...]]:
    """Split ``piece`` around every non-overlapping occurrence of ``sub``, scanning left to right."""
    parts, start, i, n = [], 0, 0, len(sub)
    while i + n <= len(piece):
        if piece[i : i + n] == sub:
            parts.extend(p for p in (piece[start:i], sub) if p)
            i += n
            start = i
        else:
            i += 1
    if start < len(piece):
        parts.append(piece[start:])
    return parts
