"""Recognition and decoding with fitted action models: a movement's class and effect, the pieces of a
demonstration decoded through the grammar, and a whole movement cut by connected recognition, each
helped by discovery's parse of the object trajectory estimated from the hand."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.base import check_is_fitted
from hoap_actions.primitives.discovery.estimator import MANIPULATION, UNKNOWN
from hoap_actions.primitives.hmm.phi_estimates import estimate_phis
from hoap_actions.primitives.labels import runs
from hoap_actions.primitives.models.class_models import EFFECT_DIM, DecodedSegment, SegmentRecognition, marker_features
from hoap_actions.primitives.models.connected_recognition import ChainedHMM, chain_classes
from hoap_actions.primitives.models.effect_continuity import effect_gap_scores
from hoap_actions.primitives.models.object_estimate import object_poses

__all__ = ["ActionDecoding"]


class ActionDecoding:
    """The recognition half of :class:`~hoap_actions.primitives.models.action_models.ActionModels`: it reads
    the fitted ``classes_``, ``grammar_``, ``discovery_``, ``fps_``, ``marker_names_`` and
    ``grasp_offset_``, and the decoding hyper-parameters."""

    def features(self, H: np.ndarray) -> np.ndarray:
        """The model input of one movement's markers ``(T, M, 3)`` or ``(T, 3M)``, checked against the models."""
        check_is_fitted(self)
        H = np.asarray(H, dtype=float)
        markers = len(self.marker_names_)
        if H.ndim not in (2, 3) or H.reshape(len(H), -1).shape[1] != 3 * markers or len(H) < 1:
            raise InvalidInputError(
                f"a movement must be (T, {markers}, 3) or (T, {3 * markers}) marker positions "
                f"({', '.join(self.marker_names_)}); got shape {H.shape}"
            )
        if not np.all(np.isfinite(H)):
            raise InvalidInputError("a movement's markers must be finite (no NaN or inf); bridge occlusion gaps first "
                                    "with hoap_actions.primitives.pipelines.mocap_cleaning.fill_gaps (learn and "
                                    "recognize do)")
        return marker_features(H, self.fps_, self.velocity)

    def recognize(self, H: np.ndarray) -> SegmentRecognition:
        """The class of one movement ``H`` (its markers), its phi (6,), and every class's log-likelihood.

        The class is the one whose chain, over its training effects, explains the displacements best:
        the evidence connected recognition (:meth:`decode`) reads, so a piece cut from a demonstration
        is classified as the decoder would classify it between those cuts. Phi is then estimated with
        the PHMMs of the ``n_candidates`` best classes (the others get none).
        """
        return self._recognize_pieces([self.features(H)])[0]

    def _recognize_pieces(self, pieces: list[np.ndarray]) -> list[SegmentRecognition]:
        """:meth:`recognize` of each piece's features, the phis of all pieces' candidates estimated in one batch."""
        chained = self.chained()
        marginals = [chained.class_scores(self.connected_log_emissions(X)) for X in pieces]
        candidates = [[int(chained.class_ids[i]) for i in np.argsort(-marginal, kind="stable")[: self.n_candidates]
                       if np.isfinite(marginal[i])] for marginal in marginals]
        jobs = [(self.classes_[c].phmm, X) for X, best in zip(pieces, candidates) for c in best]
        estimates = iter(estimate_phis(jobs, n_restarts=self.n_restarts))
        recognitions = []
        for marginal, best in zip(marginals, candidates):
            scores = {int(c): float(v) for c, v in zip(chained.class_ids, marginal)}
            if not best:  # shorter than every chain: no class explains it
                recognitions.append(SegmentRecognition(-1, np.full(EFFECT_DIM, np.nan), scores, {}))
                continue
            phis = {c: self.classes_[c].full_phi(next(estimates)) for c in best}
            recognitions.append(SegmentRecognition(best[0], phis[best[0]], scores, phis))
        return recognitions

    def decode_segments(self, segments: Sequence[np.ndarray]) -> list[SegmentRecognition]:
        """Recognise the consecutive pieces of one demonstration together, through the grammar.

        Each piece is recognised on its own, then the grammar picks the class sequence that best
        explains all of them (with the unexplained penalty and effect continuity); then, with
        ``object_vote``, the class discovery gives each piece of the object trajectory estimated from
        the hand adds to that class's score and the grammar decodes again (module docstring). Each
        returned recognition carries the decoded class and that class's phi. A piece no class
        explains, or a demonstration the strict grammar cannot parse, keeps its isolated class.
        """
        return self.decode_demonstrations([segments])[0]

    def decode_demonstrations(self, demonstrations: Sequence[Sequence[np.ndarray]]) -> list[list[SegmentRecognition]]:
        """:meth:`decode_segments` of each demonstration's pieces, the phis of all their candidates estimated
        in one batch: faster than one demonstration at a time, as the EMs that converge last share frames."""
        for segments in demonstrations:
            if isinstance(segments, np.ndarray) or not len(segments):
                raise InvalidInputError("segments must be a non-empty list of movements, one (T, M, 3) array per "
                                        "piece")
        recognitions = self._recognize_pieces([self.features(piece) for segments in demonstrations
                                               for piece in segments])
        bounds = np.cumsum([0] + [len(segments) for segments in demonstrations])
        recognitions = [recognitions[a:b] for a, b in zip(bounds[:-1], bounds[1:])]
        decoded = [self._decode(pieces) for pieces in recognitions]
        votes = self._object_votes([(segments, [r.class_id for r in pieces])
                                    for segments, pieces in zip(demonstrations, decoded)])
        return [first if vote is None else self._decode(pieces, vote)
                for pieces, first, vote in zip(recognitions, decoded, votes)]

    def object_votes(self, segments: Sequence[np.ndarray], class_ids: Sequence[int]) -> list[int] | None:
        """Each consecutive piece's class (its frames' majority) in :meth:`object_parse` of the pieces'
        markers, the manipulation being the pieces from the first to the last of ``class_ids`` that is a
        manipulation class; -1 where the parse knows no class; ``None`` when :meth:`object_parse` gives none."""
        return self._object_votes([(segments, class_ids)])[0]

    def _object_votes(self, demonstrations: Sequence[tuple[Sequence[np.ndarray], Sequence[int]]]
                      ) -> list[list[int] | None]:
        """:meth:`object_votes` of several demonstrations' (pieces, classes), parsed in one batch."""
        movements, bounds = [], []
        for segments, class_ids in demonstrations:
            lengths = [len(piece) for piece in segments]
            H = np.concatenate([np.asarray(piece, dtype=float).reshape(len(piece), -1) for piece in segments])
            movements.append((H, np.repeat(np.asarray(class_ids, dtype=int), lengths)))
            bounds.append(np.cumsum([0] + lengths))
        return [None if labels is None else
                [int(np.bincount(labels[a:b] - UNKNOWN).argmax()) + UNKNOWN for a, b in zip(cuts[:-1], cuts[1:])]
                for labels, cuts in zip(self.object_parses(movements), bounds)]

    def object_parse(self, H: np.ndarray, frame_classes: np.ndarray) -> np.ndarray | None:
        """Discovery's class of every frame (``UNKNOWN`` where it knows none) in its parse of the object
        trajectory estimated from the markers ``H`` ``(T, M, 3)`` or ``(T, 3M)``
        (:mod:`~hoap_actions.primitives.models.object_estimate`), the hand moving the object from the first to
        the last frame that ``frame_classes`` ``(T,)`` gives a manipulation class. ``None`` when the
        models cannot vote (``object_vote`` 0, no grasp offset) or no frame is a manipulation."""
        return self.object_parses([(H, frame_classes)])[0]

    def object_parses(self, movements: Sequence[tuple[np.ndarray, np.ndarray]]) -> list[np.ndarray | None]:
        """:meth:`object_parse` of several movements' ``(H, frame_classes)``: discovery parses them in one
        batch, which shares its Viterbi's steps."""
        check_is_fitted(self)
        if self.object_vote == 0 or self.grasp_offset_ is None:
            return [None] * len(movements)
        manipulations = [c for c, m in self.classes_.items() if m.kind == MANIPULATION]
        poses = {}
        for i, (H, frame_classes) in enumerate(movements):
            moving = np.flatnonzero(np.isin(frame_classes, manipulations))
            if moving.size:
                H = np.asarray(H, dtype=float).reshape(len(H), len(self.marker_names_), 3)
                poses[i] = object_poses(H, self.marker_names_, int(moving[0]), int(moving[-1]) + 1,
                                        self.grasp_offset_)
        parses = iter(self.discovery_.predict(np.concatenate(list(poses.values())), [len(p) for p in poses.values()])
                      if poses else ())
        return [next(parses) if i in poses else None for i in range(len(movements))]

    def _decode(self, recognitions: list[SegmentRecognition], votes: Sequence[int] | None = None
                ) -> list[SegmentRecognition]:
        scores = [r.log_likelihoods if r.class_id >= 0 else dict.fromkeys(self.classes_, 0.0) for r in recognitions]
        # after the unexplained penalty: a piece shorter than the voted class's chain (a brisker
        # demonstrator than the training ones) still gets the vote
        bonus = None if votes is None else [{vote: self.object_vote} if vote in self.classes_ else {} for vote in votes]
        pairs = None
        if self.continuity_weight > 0 and len(recognitions) > 1:
            pieces = {cid for cid, m in self.classes_.items() if m.kind == MANIPULATION}

            def where(rec: SegmentRecognition, part: slice) -> dict:
                return {c: phi[part] for c, phi in rec.phis.items() if c in pieces}

            pairs = [effect_gap_scores(where(a, slice(3, 6)), where(b, slice(0, 3)), float(self.continuity_weight))
                     for a, b in zip(recognitions, recognitions[1:])]
        try:
            labels, _ = self.grammar_.decode(scores, self.unexplained_penalty, pairs, bonus)
        except InvalidInputError:  # the strict grammar cannot parse these pieces: keep the isolated classes
            return recognitions
        return [
            SegmentRecognition(int(label), rec.phis.get(int(label), np.full(EFFECT_DIM, np.nan)),
                               rec.log_likelihoods, rec.phis)
            for label, rec in zip(labels, recognitions)
        ]

    def decode(self, H: np.ndarray) -> list[DecodedSegment]:
        """Cut a whole movement (its markers alone) into primitives and recognise each, with its phi.

        Connected recognition (:mod:`~hoap_actions.primitives.models.connected_recognition`): the classes'
        chains joined by the grammar, Viterbi over every frame, then again with each frame's class in
        :meth:`object_parse` ``object_vote`` nats the likelier; then each segment's phi estimated with
        its class's PHMM. A movement no grammatical path explains gives an empty list.
        """
        X = self.features(H)
        return self.decode_features(X, self.connected_log_emissions(X))

    def connected_log_emissions(self, X: np.ndarray) -> np.ndarray:
        """Log-density of every frame of the features ``X`` (:meth:`features`) under every state of the
        chained classes, ``(T, S)``: connected recognition's evidence."""
        return self.chained().log_emissions(X[:, self.connected_features()])

    def decode_features(self, X: np.ndarray, log_emissions: np.ndarray) -> list[DecodedSegment]:
        """:meth:`decode` from a movement's features and their :meth:`connected_log_emissions`, for a
        caller that uses the emissions too (the recognition report's baseline)."""
        return self.decode_movements([(X, log_emissions)])[0]

    def decode_movements(self, movements: Sequence[tuple[np.ndarray, np.ndarray]]) -> list[list[DecodedSegment]]:
        """:meth:`decode_features` of several movements' ``(X, log_emissions)``, their object parses and
        their segments' phis each computed in one batch (faster than one movement at a time)."""
        chained = self.chained()
        ids = chained.class_ids
        found = [chained.viterbi(log_emissions) for _, log_emissions in movements]
        paths = [i for i, (_, score) in enumerate(found) if np.isfinite(score)]  # none: nothing decoded
        parses = self.object_parses([(movements[i][0][:, : 3 * len(self.marker_names_)], ids[found[i][0]])
                                     for i in paths])
        labels = [self._voted_labels(movements[i][1], found[i][0], parse) for i, parse in zip(paths, parses)]
        pieces = [[(i, self.classes_[int(ids[index])], int(start), int(end)) for index, start, end in runs(path)]
                  for i, path in zip(paths, labels)]
        ok = [[end - start >= model.phmm.min_frames for _, model, start, end in cut] for cut in pieces]
        jobs = [(model.phmm, movements[i][0][start:end]) for cut, fits in zip(pieces, ok)
                for (i, model, start, end), fit in zip(cut, fits) if fit]
        estimates = iter(estimate_phis(jobs, n_restarts=self.n_restarts))
        decoded: list[list[DecodedSegment]] = [[] for _ in movements]
        for cut, fits in zip(pieces, ok):
            for (i, model, start, end), fit in zip(cut, fits):
                phi = model.full_phi(next(estimates)) if fit else np.full(EFFECT_DIM, np.nan)
                decoded[i].append(DecodedSegment(model.class_id, start, end, phi))
        return decoded

    def _voted_labels(self, log_emissions: np.ndarray, labels: np.ndarray, parse: np.ndarray | None) -> np.ndarray:
        """Each frame's class index after the object's vote: Viterbi again with each frame's class in ``parse``
        ``object_vote`` nats the likelier (``labels`` kept without a parse or a path)."""
        if parse is None:
            return labels
        chained = self.chained()
        ids = chained.class_ids
        parsed = np.searchsorted(ids, parse).clip(0, len(ids) - 1)  # ids are sorted
        voted = (ids[parsed] == parse)[:, None] & (chained.state_class[None, :] == parsed[:, None])
        relabelled, score = chained.viterbi(log_emissions + self.object_vote * voted)
        return relabelled if np.isfinite(score) else labels

    def chained(self) -> ChainedHMM:
        """The classes' chains joined by the grammar, over the training effects (built once)."""
        check_is_fitted(self)
        if getattr(self, "_chained", None) is None:
            ids = list(self.classes_)
            self._chained = chain_classes([self.classes_[c].phmm for c in ids], ids,
                                          [self.classes_[c].exit_probability for c in ids], self.grammar_,
                                          self.connected_features(), self.stay_weight)
        return self._chained

    def connected_features(self) -> np.ndarray:
        """Indices of the features connected recognition reads: the displacements when the models have
        them (module docstring), else the positions."""
        positions = 3 * len(self.marker_names_)
        return np.arange(positions, 2 * positions) if self.velocity else np.arange(positions)
