"""A particle filter in action space: each particle is (a, phi, s), a class, its effect and its PHMM state.

Propagation (the paper's "Action Tracking: PHMM-Based"):

* ``s`` advances through PHMM ``a``'s left-right chain at the rate its transition matrix gives
  (``1 - a_ss`` states per frame, the expected durations synthesis uses), times a speed drawn per
  particle, so the filter holds fast and slow performers at once. ``s`` is continuous and the pose is
  interpolated between neighbouring state means, as :meth:`ParametricHMM.synthesize` does: with a
  discrete ``s`` a fast reach falls between two means, and particles that wait where the image fits
  best never catch up.
* In manipulations and removes, a small share of particles (:data:`LEAP_SHARE` per frame) leaps ahead
  in its chain, by up to :data:`LEAP_CHAIN_SHARE` of its states (with ``far_leap_share``, another share
  leaps anywhere in the rest of it): a demonstrator who lingers and then
  moves fast (a slow lift before a quick withdrawal) leaves particles moving at a learned pace behind,
  and near the block the image does not tell them apart until the arm has gone. Approach particles do
  not leap: those that did finished their reach before the arm showed its goal, and the goal's
  estimate suffered.
* From the chain's last state the class ends with its learned exit probability; a successor is drawn
  from the grammar and starts where the previous one ended (only the end of phi is estimated). The
  effects of approach and remove are the hand's start and end, a manipulation's the object's: the
  hand's end becomes the object's start at the height the two classes' training effects differ by.
* The end moves by Brownian diffusion that cools as ``s`` advances (early frames say little about
  where the hand is going), inside the range of its class's training ends widened by 5 cm; an approach's
  end drawn at the seen block from the training ends (below) moves by a millimetre a frame at most. An approach's
  end is held where the model posing the particle sees it (:mod:`~hoap_actions.tracking.effect_bounds`).
* A small share of particles (``REDRAW_SHARE`` per frame) draws its end afresh from its class's
  training effects: the early frames of a reach say little about its goal, and once the particles
  have agreed on a wrong one, diffusion alone cannot carry them across the table to the right one.
* When the block is seen (:class:`~hoap_actions.vision.objects.ObjectLocator`), an
  approach's redrawn end lies at the block, where a training approach ended relative to its object (the
  models' ``approach_ends``: each task has its own place, a few millimetres wide; without them, the mean
  offset with a spread of centimetres), and a manipulation starts at the block: the image proposes where
  the arm is going.
* Each particle's pose strays from the state's mean by a pose state that drifts within the state's
  learned spread (the PHMM's observation density): an offset of every marker coordinate (``"offsets"``),
  or a shift of the hand with the shoulder and elbow generated from it (``"hand"``;
  :mod:`~hoap_actions.tracking.poses`).

Observation, eq. (8): the posed body is projected into the camera and its contour scored on the edge
image, ``exp(-mean_C (1 - G(c))^2 / (2 sigma^2))``, in log form (so no likelihood underflows); eq. (9)
sums the exponents over several views. Contour points below the table top (``BodyModel.hidden_below_z``)
are not scored: the camera cannot see a hand hanging below the table. Edges alone reward any contour
on clutter and cannot place an arm in front of a trunk of its colour, so with foreground masks
(:mod:`~hoap_actions.vision.silhouette`) a silhouette term joins them: the share of the
limbs' axis points off the person plus the share of the person (outside the trunk) the body leaves
uncovered, over ``2 sigma_s^2``. When the object is seen (its position each frame), its displacement
over the last few frames is evidence of the class: a manipulation moves it, approach and remove do not
(discovery's own definition); without it a hand hovering at the block reads as a manipulation and the
particles stay in one while the arm lets go. With ``object_place_m`` its place is scored too, against where
each particle's class puts it (:mod:`~hoap_actions.tracking.object_evidence`). Weights carry over between
frames; systematic resampling when the effective sample size falls below half the particles (resampling every
frame collapses the end estimates before the arm has shown where it goes). With ``lag``, each frame is also read
again that many frames later through the particles' lineage (:mod:`~hoap_actions.tracking.smoothing`).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from hoap_actions.errors import InvalidInputError
from hoap_actions.primitives.discovery.estimator import APPROACH, MANIPULATION
from hoap_actions.primitives.models.action_models import ActionModels
from hoap_actions.tracking.effect_bounds import EndHold, end_boxes, hand_offset_from_object
from hoap_actions.tracking.image_evidence import depths_or_holes, image_log_likelihoods, per_camera, within_unit_range
from hoap_actions.tracking.object_evidence import OBJECT_MOVING_M, OBJECT_STILL_M, ObjectEvidence
from hoap_actions.tracking.poses import mean_poses
from hoap_actions.tracking.poses import pose_proposal as _pose_proposal
from hoap_actions.tracking.smoothing import MAX_LAG, ParticleLineage, SmoothedFrame, tilted
from hoap_actions.tracking.tracking_models import TrackingModels
from hoap_actions.vision.body_model import BodyModel, Projector

__all__ = ["ActionTracker", "TrackedFrame", "mean_poses"]  # mean_poses: from poses, where it moved

# sigma of eq. (8), in units of 1 - G: how sharply contours are told apart (chosen with the silhouette term
# on a validation recording, docs/experiments/tracking.md): sharper, the particles agree on a goal before
# the arm shows it
OBSERVATION_SIGMA = 0.8
# Most particles a tracker takes: 250 times the paper's 400. Every particle's body is projected and
# scored in every frame; ten million of them took 6 GB before the first frame was done.
MAX_PARTICLES = 100_000
END_DIFFUSION_M = 0.005  # m per frame, std of the end point's Brownian step at a class's first state
END_DIFFUSION_FLOOR = 0.1  # share of that step left at the chain's last state (cooling, never frozen)
NEW_END_SPREAD_M = 0.05  # m, jitter around a training effect when a particle starts a class
SPEED_SPREAD = 0.3  # log-normal sigma of a particle's speed through its chain (people vary +-30 %)
SPEED_JITTER = 0.05  # per-frame log-normal change of that speed
LEAP_SHARE = 0.05  # particles per frame that leap ahead in their chain (validation recording: 0.02-0.1 tried)
LEAP_CHAIN_SHARE = 0.15  # a leap is uniform over up to this share of the chain's states (0.15-0.5 tried)
# particles per frame whose leap is uniform over the rest of their chain, as track_markers_episode asks: a filter
# held in a manipulation piece while the hand rises and leaves enters the remove at its first state, where the
# remove's lift stands between it and the hand at rest (validation `paper` 341: 21 -> 4 cm; from images it cost
# 0.1-0.2 cm, so it is off by default)
FAR_LEAP_SHARE = 0.01
REDRAW_SHARE = 0.05  # particles per frame whose end is drawn again from their class's training effects
MODE_REDRAW_SHARE = 0.01  # particles per frame whose hand mode is drawn again from the modes' prior
# m, jitter of an end drawn at the seen block: where the hand ends beside it varies by 4-5 cm (validation)
OBJECT_END_SPREAD_M = 0.045
# m, jitter of an end drawn from a training approach's end at the seen block (validation: 0.005 / 0.01 / 0.02 m)
APPROACH_END_JITTER_M = 0.005
# m per frame, the end's step of an approach whose goals are drawn at the seen block from the training ends: they
# are drawn within millimetres of a task's place, and a wider walk takes them off it (validation: 0.005 / 0.001)
APPROACH_AT_BLOCK_DIFFUSION_M = 0.001
SILHOUETTE_SIGMA = 0.6  # sigma of the silhouette term (units of the shares off / uncovered; validation recording)
# sigma of the depth term (m of truncated depth misfit) by what it weighs (validation recordings): in the filter, broad
# enough for the class posterior; on the pose estimate alone, sharper (0.005-0.02 tried)
DEPTH_SIGMA_M = {"filter": 0.02, "pose": 0.01}
MARKER_SIGMA_M = 0.2  # m, spread of an observed marker around a particle's (step_markers): broad, as a sharp likelihood
# collapses the particle set onto a class's early finishers (validation, 0.02 / 0.1 / 0.2 m: RMS 11.8 / 9.0 / 4.2 cm)
MARKERS_POSE_SHARPENING = 16.0  # the power of the markers' likelihood in the pose estimate from motion capture
RESAMPLE_BELOW = 0.5  # resample when the effective sample size is below this share of the particles
DEPTH_WEIGHS = ("pose", "filter")  # what depth images weigh: the pose estimate only, or every particle's weight
EXIT = -1  # grammar successor meaning "the demonstration is over": the particle stays at rest


@dataclass(frozen=True, eq=False)
class TrackedFrame:
    """What the tracker believes after one image.

    ``class_id``, ``state`` and ``phi`` (6,) of the most probable particle; ``class_probabilities``
    P(a) marginalised over phi and s; ``end_mean`` / ``end_std`` (3,) of phi's estimated end (m) over all
    particles, whatever their class; ``class_ends`` each class's estimate of its end (3,) (m, its
    particles' weighted mean: an approach's goal read apart from the manipulations some particles began);
    ``entropy`` (nats) of P(a, s); ``markers`` (M, 3) the weighted mean pose; ``log_likelihood`` of the
    best particle; ``reinitialised`` when no particle could explain the image.
    """

    class_id: int
    state: int
    phi: np.ndarray
    class_probabilities: Mapping[int, float]
    end_mean: np.ndarray
    end_std: np.ndarray
    entropy: float
    markers: np.ndarray
    log_likelihood: float
    reinitialised: bool = False
    class_ends: Mapping[int, np.ndarray] = field(default_factory=dict)


class ActionTracker:
    """Track a demonstrator in edge images with the learned action models (see the module docstring).

    Parameters
    ----------
    models
        fitted :class:`ActionModels` (their class PHMMs, grammar and markers), or
        :class:`~hoap_actions.tracking.tracking_models.TrackingModels` (which may carry a posture model).
    body
        the :class:`BodyModel` that turns markers into a contour.
    cameras
        one or more :class:`~hoap_actions.vision.body_model.Projector` cameras, one
        edge image (and, optionally, one foreground mask) each.
    n_particles
        particles (the paper used 400).
    observation_sigma, end_diffusion_m
        eq. (8)'s sigma; the end's Brownian step (m per frame).
    silhouette_sigma
        the silhouette term's sigma, used when :meth:`step` is given foreground masks.
    depth_sigma_m
        the depth term's sigma (m), used when :meth:`step` is given depth images; None (the default): the one
        chosen for what the depth weighs (:data:`DEPTH_SIGMA_M`).
    depth_weighs
        what the depth images weigh (:data:`DEPTH_WEIGHS`): ``"pose"`` (the default), the pose estimate only, each
        frame's and the smoothed one, as ``pose_sharpening`` does, the filter and its class posterior reading the
        colour images alone; ``"filter"``, every particle's weight, like the colour terms. Sharp enough to place the
        arm along the camera's ray, the depth term in the filter collapses the class posterior onto whichever class
        fits the moment (``docs/experiments/tracking.md``).
    object_still_m, object_moving_m
        scales of the object's seen displacement for classes that leave it at
        rest and for manipulations (:mod:`~hoap_actions.tracking.object_evidence`); ``object_still_m=None``
        turns the term off.
    pose_proposal
        how a particle's pose strays from its state's mean (:mod:`~hoap_actions.tracking.poses`):
        ``"offsets"``, every marker coordinate on its own, or ``"hand"``, the hand shifted and the shoulder
        and elbow generated from it (warns when the models carry no posture model: they come from the
        state's covariance then).
    random_state
        seed of the filter's draws.
    lag
        frames of fixed-lag smoothing behind :meth:`smoothed_frames` (0: each frame's filtered estimate; None,
        the default: no lineage is kept); the filter itself, and what :meth:`step` returns, do not depend on it.
    object_place_m
        scale (m) of the place term: the seen object against where each particle's class puts it
        (:mod:`~hoap_actions.tracking.object_evidence`); None (the default) turns it off. For exact object
        positions (motion capture, :func:`~hoap_actions.tracking.track_markers_episode` uses
        :data:`~hoap_actions.tracking.object_evidence.OBJECT_PLACE_M`), not the camera's block locator.
    far_leap_share
        particles per frame, in manipulations and removes, whose leap goes anywhere in the rest of their
        chain (0, the default: none); :func:`~hoap_actions.tracking.track_markers_episode` uses
        :data:`FAR_LEAP_SHARE`.
    pose_sharpening
        the pose estimate (each frame's and the smoothed one) weighs the particles by the frame's pose likelihood
        raised to this power rather than to 1, the class posterior and the filter staying as they are: a likelihood
        broad enough not to collapse the classes reads the pose from too many particles. 1 (the default) off;
        :func:`~hoap_actions.tracking.track_markers_episode` uses :data:`MARKERS_POSE_SHARPENING`.

    Attributes
    ----------
    hand_from_object
        (3,) m, where an approach ends relative to the block (x, y; z is the end's height),
        learned from the models' training effects unless the models give it (``TrackingModels.object_end``);
        used when :meth:`step` is told where the block is.
    """

    def __init__(self, models: ActionModels | TrackingModels, body: BodyModel, cameras: Projector | Sequence[Projector],
                 n_particles: int = 400, observation_sigma: float = OBSERVATION_SIGMA,
                 end_diffusion_m: float = END_DIFFUSION_M, silhouette_sigma: float = SILHOUETTE_SIGMA,
                 object_still_m: float | None = OBJECT_STILL_M, object_moving_m: float = OBJECT_MOVING_M,
                 pose_proposal: str = "offsets", random_state: int | np.random.Generator | None = None,
                 depth_sigma_m: float | None = None, lag: int | None = None,
                 object_place_m: float | None = None, far_leap_share: float = 0.0,
                 pose_sharpening: float = 1.0, depth_weighs: str = "pose") -> None:
        models = models if isinstance(models, TrackingModels) else TrackingModels.from_action_models(models)
        if (isinstance(n_particles, bool) or not isinstance(n_particles, (int, np.integer))
                or not 1 <= n_particles <= MAX_PARTICLES):
            raise InvalidInputError(f"n_particles must be an int in 1..{MAX_PARTICLES}; got {n_particles!r}")
        if depth_weighs not in DEPTH_WEIGHS:
            raise InvalidInputError(f"depth_weighs must be one of {list(DEPTH_WEIGHS)}; got {depth_weighs!r}")
        depth_sigma_m = DEPTH_SIGMA_M[depth_weighs] if depth_sigma_m is None else depth_sigma_m
        if not (observation_sigma > 0 and silhouette_sigma > 0 and depth_sigma_m > 0 and end_diffusion_m >= 0):
            raise InvalidInputError("observation_sigma, silhouette_sigma and depth_sigma_m must be > 0 and "
                                    "end_diffusion_m >= 0")
        if not ((object_still_m is None or object_still_m > 0) and object_moving_m > 0):
            raise InvalidInputError(f"object_still_m must be > 0 or None (off) and object_moving_m > 0; got "
                                    f"{object_still_m!r}, {object_moving_m!r}")
        if object_place_m is not None and not (np.isfinite(object_place_m) and object_place_m > 0):
            raise InvalidInputError(f"object_place_m must be > 0 (m) or None (off); got {object_place_m!r}")
        if not (isinstance(far_leap_share, (int, float)) and not isinstance(far_leap_share, bool)
                and 0.0 <= far_leap_share <= 1.0):
            raise InvalidInputError(f"far_leap_share must be a share in [0, 1]; got {far_leap_share!r}")
        if isinstance(pose_sharpening, bool) or not (isinstance(pose_sharpening, (int, float))
                                                     and 1.0 <= pose_sharpening < np.inf):
            raise InvalidInputError(f"pose_sharpening must be a finite number >= 1; got {pose_sharpening!r}")
        if lag is not None and (isinstance(lag, bool) or not isinstance(lag, (int, np.integer))
                                or not 0 <= lag <= MAX_LAG):
            raise InvalidInputError(f"lag must be None or an int in 0..{MAX_LAG} (frames); got {lag!r}")
        if tuple(body.marker_names) != tuple(models.marker_names):
            raise InvalidInputError(f"the body model's markers {list(body.marker_names)} are not the models' "
                                    f"{list(models.marker_names)}")
        self.poses = _pose_proposal(pose_proposal, models)
        if pose_proposal == "hand" and models.posture is None:
            warnings.warn("these models carry no posture model: the shoulder and elbow of poses generated from the "
                          "hand come from each PHMM state's covariance conditioned on the hand (with diagonal "
                          "covariances, the state's mean)", UserWarning, stacklevel=2)
        self.models, self.body = models, body
        self.cameras = [cameras] if hasattr(cameras, "view_matrix") else list(cameras)
        self.n_particles = int(n_particles)
        self.observation_sigma = float(observation_sigma)
        self.end_diffusion_m = float(end_diffusion_m)
        self.silhouette_sigma = float(silhouette_sigma)
        self.depth_sigma_m = float(depth_sigma_m)
        self.lag = None if lag is None else int(lag)
        self.pose_sharpening = float(pose_sharpening)
        self.depth_weighs = depth_weighs
        self.far_leap_share = float(far_leap_share)
        self._evidence = ObjectEvidence(models, object_still_m and float(object_still_m), float(object_moving_m),
                                        object_place_m and float(object_place_m))
        self._rng = np.random.default_rng(random_state)
        self._object: np.ndarray | None = None  # where the object was last seen
        self._ids = np.array(sorted(models.classes))
        self._manipulations = self._evidence.manipulations
        self._n_markers = len(models.marker_names)
        self._n_modes = 1 if models.hand_modes is None else models.hand_modes.n_modes
        self._grammar_rows = self._successor_table()
        self._approach_ends = models.approach_ends if models.object_end is None else None
        self._object_end_spread_m = OBJECT_END_SPREAD_M
        if models.object_end is not None:
            self.hand_from_object, self._object_end_spread_m = (np.asarray(models.object_end[0], float),
                                                                float(models.object_end[1]))
        elif self._approach_ends is not None:
            self.hand_from_object = np.asarray(self._approach_ends, float).mean(axis=0)
        else:
            self.hand_from_object = hand_offset_from_object(self.models.classes)
        self._end_box = end_boxes(models.classes)
        self._end_hold = EndHold(models.classes, {} if models.hand_modes is None else models.hand_modes.classes,
                                 self._n_modes)
        self.reset()

    # ----------------------------------------------------------------------------- set-up
    def _successor_table(self) -> tuple[np.ndarray, np.ndarray, dict[int, np.ndarray]]:
        """Grammar as arrays: the start distribution over class ids, and each class's successors (EXIT = end)."""
        grammar = self.models.grammar
        symbols = [int(s) for s in grammar.symbols_]
        targets = np.array([*symbols, EXIT])
        table = {int(s): grammar.transmat_[k + 1, 1:] for k, s in enumerate(symbols)}
        return targets, grammar.transmat_[0, 1:], table

    def reset(self) -> None:
        """Start a new track: particles drawn from the prior (:meth:`_draw_prior`), no frame seen."""
        self._lineage = None if self.lag is None else ParticleLineage(self.lag)
        self._object = None
        self._seen_whole = False
        self._smoothed: list[SmoothedFrame] = []
        self._frames_seen = 0
        self._draw_prior()

    @property
    def object_seen(self) -> np.ndarray | None:
        """Where the object was last seen whole (3,) (m; partly hidden until a first whole sighting), None before any
        sighting."""
        return None if self._object is None else self._object.copy()

    def smoothed_frames(self, final: bool = False) -> list[SmoothedFrame]:
        """The fixed-lag estimates (:mod:`~hoap_actions.tracking.smoothing`) ready since the last call: frame
        ``t``'s once frame ``t + lag`` was weighed; ``final`` (the track is over) reads the frames still
        waiting with the last frame's weights. With ``lag=0``, each frame's filtered estimate."""
        if self._lineage is None:
            raise InvalidInputError(f"this tracker keeps no lineage to smooth with: make it with lag=0..{MAX_LAG}")
        if final:
            self._smoothed += self._lineage.flush(self.weights)
        ready, self._smoothed = self._smoothed, []
        return ready

    def _draw_prior(self) -> None:
        """Particles drawn from the grammar's first classes at their first state, ends from training effects."""
        targets, start_row, _ = self._grammar_rows
        first = self._rng.choice(targets, size=self.n_particles, p=start_row / start_row.sum())
        first = np.where(first == EXIT, targets[np.argmax(start_row[:-1])], first)
        self.class_id = first.astype(int)
        self.mode = self._draw_modes(self.n_particles)
        self.state = np.zeros(self.n_particles)
        self.speed = np.exp(self._rng.normal(0.0, SPEED_SPREAD, self.n_particles))
        self.offset = np.zeros((self.n_particles, self.poses.dim))
        self.start = np.zeros((self.n_particles, 3))
        self.end = np.zeros((self.n_particles, 3))
        self.resting = np.zeros(self.n_particles, dtype=bool)
        self.object_at = np.full((self.n_particles, 3), np.nan)
        self.weights = np.full(self.n_particles, 1.0 / self.n_particles)
        self._evidence.reset()
        for cid in np.unique(self.class_id):
            chosen = np.flatnonzero(self.class_id == cid)
            effects = self._training_effects(cid, chosen.size)
            self.start[chosen] = effects[:, :3]
            self.end[chosen] = effects[:, 3:] + self._rng.normal(0.0, NEW_END_SPREAD_M, (chosen.size, 3))

    def _draw_modes(self, n: int) -> np.ndarray:
        """``n`` hand modes drawn from the models' prior (all 0 for models without modes, drawing nothing)."""
        if self.models.hand_modes is None:
            return np.zeros(n, dtype=int)
        return self._rng.choice(self._n_modes, size=n, p=self.models.hand_modes.prior)

    def _training_effects(self, class_id: int, n: int) -> np.ndarray:
        """``n`` full effects (6,) drawn from class ``class_id``'s training effects."""
        model = self.models.classes[class_id]
        reduced = model.phmm.train_phi_[self._rng.integers(0, len(model.phmm.train_phi_), size=n)]
        return model.centre + np.einsum("np,kp->nk", reduced, model.basis)

    # ----------------------------------------------------------------------------- the filter
    def step(self, edges: np.ndarray | Sequence[np.ndarray],
             foreground: np.ndarray | Sequence[np.ndarray] | None = None,
             object_position: np.ndarray | None = None,
             depth: np.ndarray | Sequence[np.ndarray] | None = None, object_whole: bool = True) -> TrackedFrame:
        """Propagate, weigh by the edge image(s) (one per camera, as from :func:`edge_image`) and, when given,
        the foreground mask(s) (:class:`~hoap_actions.vision.silhouette.BackgroundSubtractor`) and depth
        image(s) (m along each camera's view axis, NaN where not measured), resample.
        ``object_position`` (3,), m: the block where the camera sees it this frame (None: not seen);
        ``object_whole`` False: it is partly hidden (a hand over it), its sighting evidence of motion only, goals
        still drawn where it was last seen whole (before any whole sighting, where the partial ones place it)."""
        images = per_camera(edges, self.cameras, "edge image", within_unit_range)
        masks = None if foreground is None else per_camera(foreground, self.cameras, "foreground mask",
                                                           within_unit_range)
        depths = None if depth is None else per_camera(depth, self.cameras, "depth image", depths_or_holes)
        self._see_object(object_position, bool(object_whole))
        self._propagate()
        markers = self.markers()
        colour, depth_evidence = self._image_evidence(markers, images, masks, depths)
        if depth_evidence is not None and self.depth_weighs == "filter":  # every particle's weight, not the pose's
            colour, depth_evidence = colour + depth_evidence, None
        return self._weigh(markers, colour, depth_evidence)

    def step_markers(self, observed: np.ndarray, sigma_m: float = MARKER_SIGMA_M,
                     object_position: np.ndarray | None = None) -> TrackedFrame:
        """Propagate and weigh by observed 3-D markers ``(M, 3)`` (m; NaN: a marker not seen) instead of
        images: each seen marker an isotropic Gaussian of ``sigma_m`` around the particle's. Recognition
        from motion capture, and the filter's own error when vision is taken out of it.
        ``object_position`` as for :meth:`step` (the object's captured centre)."""
        observed = np.asarray(observed, dtype=float)
        if observed.shape != (self._n_markers, 3):
            raise InvalidInputError(f"observed markers must be ({self._n_markers}, 3) in m; got {observed.shape}")
        if not (np.isfinite(sigma_m) and sigma_m > 0):
            raise InvalidInputError(f"sigma_m must be > 0 (m); got {sigma_m!r}")
        self._see_object(object_position)
        self._propagate()
        markers = self.markers()
        seen = np.isfinite(observed).all(axis=1)
        squared = np.sum((markers[:, seen] - observed[seen]) ** 2, axis=(1, 2))
        return self._weigh(markers, -squared / (2.0 * sigma_m**2))

    def _see_object(self, object_position: np.ndarray | None, whole: bool = True) -> None:
        """Check where the object is seen this frame (None: not seen) and remember it: its motion evidence takes
        this frame's sighting, the goals drawn at it the last whole one (a block under the hand is where it was
        last seen whole); until a first whole sighting, the partial ones (a block that something in front of the
        camera hides from the start is nearer its partial sighting than the prior's goals)."""
        if object_position is not None:
            object_position = np.asarray(object_position, dtype=float)
            if object_position.shape != (3,) or not np.all(np.isfinite(object_position)):
                raise InvalidInputError(f"object_position must be a finite (3,) position in m or None; "
                                        f"got {object_position!r}")
            if whole or not self._seen_whole:
                self._object = object_position
            self._seen_whole |= whole
        self._evidence.see(object_position)

    def _weigh(self, markers: np.ndarray, likelihood: np.ndarray, pose_evidence: np.ndarray | None = None
               ) -> TrackedFrame:
        """Weights times the frame's likelihood (log) and the object's motion term, the frame's summary,
        resampling when due; a frame that no particle explains starts the filter again from its prior.
        ``pose_evidence`` (log, per particle) weighs the pose estimate only, beside the sharpening's tilt."""
        if self._object is not None:  # where the object was when a particle's class began: here, if not seen before
            self.object_at[~np.isfinite(self.object_at[:, 0])] = self._object
        tilt = (self.pose_sharpening - 1.0) * likelihood if self.pose_sharpening != 1.0 else None
        if pose_evidence is not None:
            tilt = pose_evidence if tilt is None else tilt + pose_evidence
        likelihood = (likelihood + self._evidence.motion_log_likelihood(self.class_id, self.resting)
                      + self._evidence.place_log_likelihood(self.class_id, self.state, self.resting, self.object_at))
        reinitialised = not np.any(np.isfinite(likelihood))
        if reinitialised:  # nothing explains the image: start again from the prior, never NaN
            if self._lineage is not None:
                self._smoothed += self._lineage.flush(self.weights)
            self._draw_prior()
            markers = self.markers()
            likelihood = np.zeros(self.n_particles)
            tilt = None
        with np.errstate(divide="ignore"):  # a weight that underflowed to 0 stays 0 (log -inf), never NaN
            log_weights = likelihood + np.log(self.weights)
        weights = np.exp(log_weights - log_weights.max())
        weights /= weights.sum()
        frame = self._summary(weights, markers, float(likelihood.max()), reinitialised, tilt)
        self.weights = weights
        if self._lineage is not None:
            self._smoothed += self._lineage.push(self._frames_seen, markers, self.class_id, weights, tilt)
        self._frames_seen += 1
        if 1.0 / np.sum(weights**2) < RESAMPLE_BELOW * self.n_particles:
            self._resample(weights)
        return frame

    def _propagate(self) -> None:
        targets, _, table = self._grammar_rows
        if self.models.hand_modes is not None:  # a few particles try another way of holding the hand
            redraw = np.flatnonzero(self._rng.random(self.n_particles) < MODE_REDRAW_SHARE)
            self.mode[redraw] = self._draw_modes(redraw.size)
        u = self._rng.random(self.n_particles)
        leaving, successors = [], []
        for cid in np.unique(self.class_id):
            chosen = np.flatnonzero((self.class_id == cid) & ~self.resting)
            if not chosen.size:
                continue
            model = self.models.classes[cid]
            k = model.phmm.n_states
            rate = 1.0 - np.diagonal(model.phmm.transmat_)
            self.speed[chosen] *= np.exp(self._rng.normal(0.0, SPEED_JITTER, chosen.size))
            last = self.state[chosen] >= k - 1
            s = np.minimum(self.state[chosen], k - 1)
            leaps = self._rng.random(chosen.size) < LEAP_SHARE
            leap = leaps * self._rng.uniform(0.0, LEAP_CHAIN_SHARE * k, chosen.size) * (model.kind != APPROACH)
            if self.far_leap_share > 0 and model.kind != APPROACH:
                far = self._rng.random(chosen.size) < self.far_leap_share
                leap = np.where(far, self._rng.uniform(0.0, 1.0, chosen.size) * (k - 1 - s), leap)
            self.state[chosen] = np.minimum(s + rate[s.astype(int)] * self.speed[chosen] + leap, k - 1)
            self.offset[chosen] = self.poses.drift(cid, s, self.offset[chosen], self._rng)
            cooling = END_DIFFUSION_FLOOR + (1.0 - END_DIFFUSION_FLOOR) * (1.0 - s / max(k - 1, 1))
            at_block = model.kind == APPROACH and self._object is not None and self._approach_ends is not None
            diffusion = min(self.end_diffusion_m, APPROACH_AT_BLOCK_DIFFUSION_M) if at_block else self.end_diffusion_m
            step = self._rng.normal(0.0, 1.0, (chosen.size, 3)) * (diffusion * cooling)[:, None]
            self.end[chosen] = np.clip(self.end[chosen] + step, *self._end_box[cid])
            redraw = chosen[self._rng.random(chosen.size) < REDRAW_SHARE]
            if redraw.size and model.kind == APPROACH and self._object is not None:
                self.end[redraw] = self._end_at_object(redraw.size)
            elif redraw.size:
                effects = self._training_effects(cid, redraw.size)
                fresh = effects[:, 3:] - effects[:, :3] + self.start[redraw] if model.kind == MANIPULATION \
                    else effects[:, 3:]  # a manipulation's end: a learned displacement from its own start
                self.end[redraw] = fresh + self._rng.normal(0.0, NEW_END_SPREAD_M, (redraw.size, 3))
            ending = chosen[last & (u[chosen] < model.exit_probability)]
            leaving.append(ending)
            successors.append(self._rng.choice(targets, size=ending.size, p=table[cid] / table[cid].sum()))
        if leaving:  # after every class has moved: a particle that changes class moves once per frame
            self._switch(np.concatenate(leaving), np.concatenate(successors))
        self._end_hold.hold(self.class_id, self.mode, self.end)

    def _end_at_object(self, n: int) -> np.ndarray:
        """``n`` approach ends drawn around the hand's learned places at the seen block: training approaches'
        ends moved to it (when the models carry them), else their mean offset with a broad spread."""
        if self._approach_ends is not None:
            ends = self._approach_ends[self._rng.integers(0, len(self._approach_ends), n)]
            centre = np.column_stack([self._object[:2] + ends[:, :2], ends[:, 2]])
            return centre + self._rng.normal(0.0, APPROACH_END_JITTER_M, (n, 3))
        centre = np.array([*(self._object[:2] + self.hand_from_object[:2]), self.hand_from_object[2]])
        return centre + self._rng.normal(0.0, self._object_end_spread_m, (n, 3))

    def _switch(self, particles: np.ndarray, successors: np.ndarray) -> None:
        """Particles that finished their class start the next one where the last ended (EXIT: rest there).

        A manipulation starts at the object: at the seen block after an approach (without one, at the
        approach's end moved to the object's height), at the previous manipulation's end after a
        manipulation (the paper's rule: the particle keeps its own account of where the pushed block is);
        approach and remove start at the particle's own hand.
        """
        self.resting[particles[successors == EXIT]] = True
        if not particles.size:
            return
        hands = self.markers(particles)[:, self.models.hand_marker]
        for cid in np.unique(successors[successors != EXIT]):
            rows = np.flatnonzero(successors == cid)
            chosen = particles[rows]
            effects = self._training_effects(int(cid), chosen.size)
            new = self.models.classes[int(cid)]
            if new.kind == MANIPULATION and self._object is not None:  # after an approach it starts at the seen block
                start = np.tile([*self._object[:2], new.centre[2]], (chosen.size, 1))
                chained = np.isin(self.class_id[chosen], self._manipulations)
                start[chained] = self.end[chosen[chained]]  # after a manipulation, where that one ended
                end = start + effects[:, 3:] - effects[:, :3]
            elif new.kind == MANIPULATION:  # the object moves by a learned displacement
                previous_end_height = np.array([self.models.classes[int(c)].centre[5] for c in self.class_id[chosen]])
                start = self.end[chosen].copy()
                start[:, 2] += new.centre[2] - previous_end_height
                end = start + effects[:, 3:] - effects[:, :3]
            else:
                start, end = hands[rows], effects[:, 3:]
            # the object when the new class begins: as seen, or moved as the class that ends moves it
            self.object_at[chosen] = self._object if self._object is not None else \
                self.object_at[chosen] + self._evidence.moved(self.class_id[chosen])
            self.class_id[chosen], self.state[chosen] = int(cid), 0.0
            self.speed[chosen] = np.exp(self._rng.normal(0.0, SPEED_SPREAD, chosen.size))
            self.start[chosen] = start
            self.end[chosen] = end + self._rng.normal(0.0, NEW_END_SPREAD_M, (chosen.size, 3))

    def markers(self, particles: np.ndarray | None = None) -> np.ndarray:
        """The body pose ``(n, M, 3)`` of ``particles`` (indices; all by default): each one's PHMM mean
        markers (its class's model for its hand mode) at its phi, between states ``floor(s)`` and ``ceil(s)``
        (:func:`mean_poses`, unchecked), moved by its pose state (:attr:`poses`)."""
        particles = np.arange(self.n_particles) if particles is None else np.asarray(particles)
        out = np.empty((particles.size, self._n_markers, 3))
        keys = self.class_id[particles] * self._n_modes + self.mode[particles]
        for key in np.unique(keys):
            rows = np.flatnonzero(keys == key)
            chosen = particles[rows]
            cid, mode = divmod(int(key), self._n_modes)
            phi = np.hstack([self.start[chosen], self.end[chosen]])
            pose = self.poses.pose(cid, self.state[chosen], phi, self.offset[chosen], mode)
            out[rows] = pose.reshape(-1, self._n_markers, 3)
        return out

    def _image_evidence(self, markers: np.ndarray, images: list[np.ndarray], masks: list[np.ndarray] | None = None,
                        depths: list[np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray | None]:
        """Eq. (8) / (9) in log form, per particle: ``-sum_views mean_C (1 - G(c))^2 / (2 sigma^2)`` over the contour
        points not hidden by the table (off-image points count as 1), with foreground masks F each view adding
        ``-(mean_limbs (1 - F) + uncovered) / (2 sigma_s^2)``; and apart, with depth images, ``-sum_views misfit /
        (2 sigma_d^2)`` (None without them) (:mod:`~hoap_actions.tracking.image_evidence`)."""
        mean_pose = None if masks is None else np.sum(self.weights[:, None, None] * markers, axis=0)
        return image_log_likelihoods(self.body, self.cameras, markers, images, masks, depths, mean_pose,
                                     (self.observation_sigma, self.silhouette_sigma, self.depth_sigma_m))

    def _summary(self, weights: np.ndarray, markers: np.ndarray, best_ll: float, reinitialised: bool,
                 tilt: np.ndarray | None = None) -> TrackedFrame:
        best = int(np.argmax(weights))
        classes, of_class = np.unique(self.class_id, return_inverse=True)
        probabilities = dict(zip(classes.tolist(), np.bincount(of_class, weights).tolist()))
        _, of_pair = np.unique(np.stack([self.class_id, self.state.astype(int)]), axis=1, return_inverse=True)
        p = np.bincount(of_pair.ravel(), weights)
        p = p[p > 0]
        mean = np.sum(weights[:, None] * self.end, axis=0)
        class_weight = np.bincount(of_class, weights)
        class_ends = np.stack([np.bincount(of_class, weights * self.end[:, k]) for k in range(3)], axis=1)
        class_ends = {int(c): class_ends[i] / class_weight[i] for i, c in enumerate(classes) if class_weight[i] > 0}
        std = np.sqrt(np.maximum(np.sum(weights[:, None] * (self.end - mean) ** 2, axis=0), 0.0))
        return TrackedFrame(
            class_id=int(self.class_id[best]), state=int(self.state[best]),
            phi=np.r_[self.start[best], self.end[best]], class_probabilities=probabilities, end_mean=mean,
            end_std=std, entropy=max(0.0, float(-np.sum(p * np.log(p)))),
            markers=np.sum(tilted(weights, tilt)[:, None, None] * markers, axis=0),
            log_likelihood=best_ll, reinitialised=reinitialised, class_ends=class_ends)

    def _resample(self, weights: np.ndarray) -> None:
        """Systematic resampling: one uniform draw, N evenly spaced pointers into the cumulative weights."""
        positions = (self._rng.random() + np.arange(self.n_particles)) / self.n_particles
        index = np.minimum(np.searchsorted(np.cumsum(weights), positions), self.n_particles - 1)
        if self._lineage is not None:
            self._lineage.resampled(index)
        self.class_id, self.state, self.speed = self.class_id[index], self.state[index], self.speed[index]
        self.mode = self.mode[index]
        self.offset = self.offset[index]
        self.start, self.end, self.resting = self.start[index], self.end[index], self.resting[index]
        self.object_at = self.object_at[index]
        self.weights = np.full(self.n_particles, 1.0 / self.n_particles)
