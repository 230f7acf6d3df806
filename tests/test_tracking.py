"""Tracking in action space: edge images, the body model's contour, the particle filter."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.envs.camera import PIXEL_SAMPLE_UV, Camera
from hoap_actions.errors import InvalidInputError
from hoap_actions.models.shipped import load_default_models
from hoap_actions.tracking.action_tracker import LEAP_CHAIN_SHARE, LEAP_SHARE, ActionTracker, mean_poses
from hoap_actions.tracking.image_evidence import depth_misfit, silhouette_misfit
from hoap_actions.vision.body_model import BodyModel, Capsule
from hoap_actions.vision.edges import edge_image
from hoap_actions.vision.silhouette import BackgroundSubtractor

MARKERS = ("shoulder", "elbow", "wrist", "index_tip", "index_knuckle", "thumb_tip")
TORSO_BASE = np.array([-0.47, 0.25, -0.10])  # the demonstration scene's lumbar joint
CAMERA = Camera(eye=(0.3, -0.8, 0.45), target=(-0.25, 0.05, 0.05), fov_deg=55, width=320, height=240)


# ------------------------------------------------------------------------------------------ edges
def test_edge_image_is_one_on_edges_and_zero_far_from_them():
    image = np.zeros((60, 80), np.uint8)
    image[20:40, 30:50] = 200
    G = edge_image(image)
    assert G.dtype == np.float32 and G.shape == (60, 80)
    assert G.max() == pytest.approx(1.0)
    assert G[20, 40] > 0.5 and G[30, 30] > 0.5           # on the square's outline
    assert G[30, 40] < 0.05 and G[5, 5] < 0.05            # its inside and far outside: no edge
    assert G[30, 27] > G[30, 24] > G[30, 20]              # the pull falls off with distance


def test_edge_image_bad_input():
    for bad, match in ((np.zeros((60, 80), np.uint8), "no edges"), (np.zeros((4, 4), np.uint8), "H, W >= 8"),
                       (np.zeros((20, 20), np.int32), "dtype"), (np.full((20, 20), np.nan), "finite"),
                       (np.zeros((20, 20, 2), np.uint8), "colour")):
        with pytest.raises(InvalidInputError, match=match):
            edge_image(bad)


# ------------------------------------------------------------------------------------- body model
def test_capsule_contour_lies_at_the_projected_radius_from_its_axis():
    """A capsule across the view at depth d: its sides are f r / d pixels from the projected axis
    (f = h / (2 tan(fov / 2))), the pinhole's answer; the axis through the image centre lies on the row and
    column the renderer samples there (PIXEL_SAMPLE_UV)."""
    camera = Camera(eye=(1.0, 0.0, 0.0), target=(0.0, 0.0, 0.0), fov_deg=60.0, width=200, height=200)
    body = BodyModel(("a", "b"), np.zeros(3), capsules=(Capsule("a", "b", 0.05),), points_per_side=5)
    markers = np.array([[[0.0, -0.1, 0.0], [0.0, 0.1, 0.0]]])
    pixels = body.contour(body.project(markers, camera))[0]
    focal = 100.0 / np.tan(np.radians(30.0))
    sides = pixels[:10]
    centre_u, centre_v = 100.0 - np.asarray(PIXEL_SAMPLE_UV)
    np.testing.assert_allclose(np.abs(sides[:, 1] - centre_v), focal * 0.05 / 1.0, rtol=1e-6)
    np.testing.assert_allclose(np.sort(pixels[10:, 0]), centre_u + np.array([-1, 1]) * focal * 0.15, rtol=1e-6)
    assert body.n_points == 12


def test_covers_is_the_projected_capsule_and_the_table_hides_what_is_below_it():
    """Across the view at depth 1 m: a pixel on the axis and one within the projected radius plus the
    1 px margin are covered, one beyond it is not; points of the capsule below ``hidden_below_z`` come out as NaN."""
    camera = Camera(eye=(1.0, 0.0, 0.0), target=(0.0, 0.0, 0.0), fov_deg=60.0, width=200, height=200)
    body = BodyModel(("a", "b"), np.zeros(3), capsules=(Capsule("a", "b", 0.05),), points_per_side=5)
    bodies = body.project(np.array([[[0.0, -0.1, 0.0], [0.0, 0.1, 0.0]]]), camera)
    radius = 100.0 / np.tan(np.radians(30.0)) * 0.05
    u, v = 100.0 - np.asarray(PIXEL_SAMPLE_UV)  # where the image centre shows
    pixels = np.array([[u, v], [u, v + radius + 0.5], [u, v + radius + 1.5], [0.0, 0.0]])
    np.testing.assert_array_equal(body.covers(bodies, pixels)[0], [True, True, False, False])
    assert not np.isnan(body.contour(bodies)).any() and body.interior(bodies).shape == (1, 5, 2)
    tilted = BodyModel(("a", "b"), np.zeros(3), capsules=(Capsule("a", "b", 0.05),), points_per_side=5,
                       hidden_below_z=0.0)
    bodies = tilted.project(np.array([[[0.0, 0.0, -0.1], [0.0, 0.0, 0.1]]]), camera)  # half below z = 0
    hidden = np.isnan(tilted.interior(bodies)[0, :, 0])
    np.testing.assert_array_equal(hidden, [True, True, False, False, False])  # t = 0, 0.25 below; 0.5 on it
    assert np.isnan(tilted.contour(bodies)).any() and not np.isnan(tilted.contour(bodies, hide=False)).any()


def test_background_subtraction_finds_the_person_not_the_noise():
    rng = np.random.default_rng(0)
    empty = np.full((60, 80, 3), 120, np.uint8)
    frame = empty.copy()
    frame[20:40, 30:50] = (170, 110, 120)  # 50 levels off in one channel: 20 % of full intensity
    noisy = [np.clip(a + rng.normal(0.0, 255 * 0.03, a.shape), 0, 255).astype(np.uint8) for a in (empty, frame)]
    F = BackgroundSubtractor(noisy[0])(noisy[1])
    assert F.dtype == np.float32 and F.shape == (60, 80)
    assert F[24:36, 34:46].min() > 0.99 and F[:10].max() == 0.0 and F[:, :20].max() == 0.0
    assert BackgroundSubtractor(empty)(empty.astype(np.float32) / 255).max() == 0.0  # float images work too
    with pytest.raises(InvalidInputError, match="background's size"):
        BackgroundSubtractor(empty)(empty[:50])
    with pytest.raises(InvalidInputError, match="threshold"):
        BackgroundSubtractor(empty, threshold=0.0)
    with pytest.raises(InvalidInputError, match="dtype"):
        BackgroundSubtractor(empty.astype(np.int16))


def test_body_model_needs_the_models_markers():
    with pytest.raises(InvalidInputError, match="needs markers"):
        BodyModel(("shoulder", "elbow"), TORSO_BASE)


# ------------------------------------------------------------------------------------- the filter
@pytest.fixture(scope="module")
def models():
    return load_default_models()


@pytest.fixture(scope="module")
def reach(models):
    """A reach towards the table's centre as the tracker poses it: synthesised by the shipped approach's thin-plate
    refit for the most frequent way of holding the hand (its hand mode), which the tracker poses most approaches
    with: (T, 6, 3)."""
    approach = next(cid for cid, c in models.classes_.items() if c.kind == "approach")
    model = models.hand_modes_.classes[(approach, int(np.argmax(models.hand_modes_.prior)))]
    with np.errstate(all="ignore"):
        phi = model.centre.copy()
        phi[3:5] += [0.05, -0.04]
        movement = models._synthesize(model, phi, None)
    return approach, phi, movement


def images(body, movement):
    for pose in movement:
        picture = body.draw(np.full((CAMERA.height, CAMERA.width, 3), 90, np.uint8), pose, CAMERA, (220, 180, 150),
                            filled=True)
        yield edge_image(picture)


def log_likelihood(tracker, poses, edges, masks=None, depths=None):
    """The tracker's image log-likelihood of ``poses``: its colour and depth terms summed."""
    colour, depth = tracker._image_evidence(poses, edges, masks, depths)
    return colour if depth is None else colour + depth


def test_likelihood_prefers_the_true_pose(models, reach):
    _, _, movement = reach
    body = BodyModel(models.marker_names_, TORSO_BASE)
    tracker = ActionTracker(models, body, CAMERA, n_particles=3, random_state=0)
    t = len(movement) * 3 // 4
    G = next(iter(images(body, movement[t:t + 1])))
    moved = movement[t] + np.array([0.0, 0.05, 0.0])
    bent = movement[t].copy()
    bent[1:] += [0.0, 0.0, 0.05]
    scores = log_likelihood(tracker, np.stack([movement[t], moved, bent]), [G])
    assert scores[0] > scores[1] and scores[0] > scores[2]


def silhouettes(body, movement):
    """The foreground masks of the filled bodies of :func:`images` against an empty grey picture."""
    empty = np.full((CAMERA.height, CAMERA.width, 3), 90, np.uint8)
    subtract = BackgroundSubtractor(empty)
    for pose in movement:
        yield subtract(body.draw(empty, pose, CAMERA, (220, 180, 150), filled=True))


def test_silhouette_term_prefers_the_true_pose_and_is_small_on_it(models, reach):
    """The misfit of the true pose is small (its limbs on the person, the person covered but for the
    mask's fringe); a hand 5 cm off or an elbow 5 cm high leaves part of the person uncovered and puts
    limb points off it."""
    _, _, movement = reach
    body = BodyModel(models.marker_names_, TORSO_BASE)
    tracker = ActionTracker(models, body, CAMERA, n_particles=3, random_state=0)
    t = len(movement) * 3 // 4
    F = next(iter(silhouettes(body, movement[t:t + 1])))
    poses = np.stack([movement[t], movement[t] + [0.0, 0.05, 0.0], movement[t] + [0.0, 0.0, 0.05]])
    poses[2, 0] = movement[t, 0]  # the shoulder stays: the arm bends instead
    misfit = silhouette_misfit(body, body.project(poses, CAMERA), poses.mean(axis=0), F, CAMERA)  # weights equal
    assert misfit[0] < 0.15 and misfit[1] > misfit[0] + 0.1 and misfit[2] > misfit[0] + 0.1
    G = next(iter(images(body, movement[t:t + 1])))
    with_masks = log_likelihood(tracker, poses, [G], [F])
    np.testing.assert_allclose(log_likelihood(tracker, poses, [G]) - with_masks,
                               misfit / (2 * tracker.silhouette_sigma**2))


def test_tracks_a_reach_better_than_standing_still(models, reach):
    """On edge images of a synthesised reach, for each of three seeds the filter's pose estimate and its class
    beat the trivial answers (the arm held at its first pose; a class on fewer than 70 % of frames), and its
    estimate of where the hand goes ends within 10 cm of the truth in the median run. Edges alone do not pin the
    goal (over 12 seeds its end lands 1.5-14 cm off; the medians of four triples 4.1-8.8 cm): the seen block's
    test below asks for more."""
    approach, phi, movement = reach
    body = BodyModel(models.marker_names_, TORSO_BASE)
    edges = list(images(body, movement))
    still = np.sqrt(np.mean(np.sum((movement[:1] - movement) ** 2, axis=2)))
    end_errors = []
    for seed in range(3):
        tracker = ActionTracker(models, body, CAMERA, n_particles=200, random_state=seed)
        frames = [tracker.step(G) for G in edges]
        estimate = np.array([f.markers for f in frames])
        assert np.sqrt(np.mean(np.sum((estimate - movement) ** 2, axis=2))) < 0.35 * still
        assert np.mean([f.class_probabilities.get(approach, 0.0) > 0.5 for f in frames]) > 0.7
        assert all(np.isfinite(f.entropy) and f.entropy >= 0.0 for f in frames)
        end_errors.append(np.linalg.norm(frames[-1].end_mean[:2] - phi[3:5]))
    assert np.median(end_errors) < 0.10


def test_the_seen_block_draws_the_reach_goal_towards_it(models, reach):
    """With the block seen where the learned hand-to-object offset puts the reach's true end, the estimated
    end is nearer the truth than without it, for each of three seeds, and so it is when the block is seen in
    the first ten frames only (then hidden: goals are drawn where it was last seen); a manipulation starts at
    the block after an approach, and where the previous manipulation ended after one."""
    approach, phi, movement = reach
    body = BodyModel(models.marker_names_, TORSO_BASE)
    edges = list(images(body, movement))
    errors = {}
    for frames_seen in (0, len(edges), 10):
        for seed in range(3):
            tracker = ActionTracker(models, body, CAMERA, n_particles=200, random_state=seed)
            block = np.r_[phi[3:5] - tracker.hand_from_object[:2], 0.025]
            frames = [tracker.step(G, object_position=block if t < frames_seen else None) for t, G in enumerate(edges)]
            errors[frames_seen, seed] = np.linalg.norm(frames[-1].end_mean[:2] - phi[3:5])
    assert all(errors[len(edges), seed] < errors[0, seed] and errors[10, seed] < errors[0, seed] for seed in range(3))
    manipulation = next(cid for cid, c in models.classes_.items() if c.kind == "manipulation")
    tracker.class_id[:5] = approach
    tracker._switch(np.arange(5), np.full(5, manipulation))
    np.testing.assert_allclose(tracker.start[:5, :2], np.tile(block[:2], (5, 1)))
    pushed_to = tracker.end[:5].copy()  # a manipulation after a manipulation starts where the first one ended
    tracker._switch(np.arange(5), np.full(5, manipulation))
    np.testing.assert_allclose(tracker.start[:5], pushed_to)


def test_a_few_particles_leap_ahead_in_their_chain_by_at_most_the_set_share(models):
    """One propagation from the middle of each class's chain: the advance beyond the learned pace
    (rate x the particle's speed) is zero for all but about LEAP_SHARE of the manipulation and remove
    particles and for every approach particle, never negative, and at most LEAP_CHAIN_SHARE of the
    chain; no state passes the chain's last."""
    body = BodyModel(models.marker_names_, TORSO_BASE)
    tracker = ActionTracker(models, body, CAMERA, n_particles=20000, random_state=0)
    tracked = tracker.models.classes  # the classes the tracker runs: approach and remove are the pose classes
    tracker.class_id = np.resize(sorted(tracked), tracker.n_particles)  # every class, not only the first
    sizes = np.array([tracked[c].phmm.n_states for c in tracker.class_id])
    tracker.state = np.floor((sizes - 1) / 2.0)
    before, classes = tracker.state.copy(), tracker.class_id.copy()
    tracker._propagate()
    long_chains = sizes >= 10  # from mid-chain, no advance reaches their last state
    assert np.array_equal(tracker.class_id[long_chains], classes[long_chains]) and np.all(tracker.state <= sizes - 1)
    rates = np.array([1.0 - tracked[c].phmm.transmat_[int(s), int(s)] for c, s in zip(classes, before)])
    approach = np.array([tracked[c].kind == "approach" for c in classes])
    leap = tracker.state - before - rates * tracker.speed
    assert np.any(approach & long_chains) and np.all(np.abs(leap[approach & long_chains]) < 1e-9)
    leap, sizes = leap[long_chains & ~approach], sizes[long_chains & ~approach]
    assert np.all(leap > -1e-9) and np.all(leap <= LEAP_CHAIN_SHARE * sizes + 1e-9)
    share = np.mean(leap > 1e-9)
    half_width = 4.0 * np.sqrt(LEAP_SHARE * (1 - LEAP_SHARE) / leap.size)
    assert abs(share - LEAP_SHARE) < half_width


def test_tracking_from_markers_follows_the_reach_closely(models, reach):
    """Given the synthesised reach's own markers, the filter's pose is within 2 cm RMS of them, it names the
    approach on nearly every frame, and it finds the reach's end within 3 cm, for each of three seeds."""
    approach, phi, movement = reach
    body = BodyModel(models.marker_names_, TORSO_BASE)
    for seed in range(3):
        tracker = ActionTracker(models, body, CAMERA, n_particles=200, random_state=seed)
        frames = [tracker.step_markers(pose, sigma_m=0.02) for pose in movement]
        estimate = np.array([f.markers for f in frames])
        assert np.sqrt(np.mean(np.sum((estimate - movement) ** 2, axis=2))) < 0.02
        assert np.mean([max(f.class_probabilities, key=f.class_probabilities.get) == approach for f in frames]) > 0.9
        assert np.linalg.norm(frames[-1].end_mean - phi[3:]) < 0.03


def test_a_marker_not_seen_is_left_out_of_the_likelihood(models, reach):
    """A NaN marker changes nothing of the weights but that marker's share: the same seed, the same
    propagation, weights as if the marker had not been in the model."""
    _, _, movement = reach
    body = BodyModel(models.marker_names_, TORSO_BASE)
    observed = movement[10].copy()
    observed[1] = np.nan
    runs = []
    for sigma in (0.02, 0.05):
        tracker = ActionTracker(models, body, CAMERA, n_particles=50, random_state=1)
        tracker.step_markers(observed, sigma_m=sigma)
        runs.append(tracker)
    markers = runs[0].markers()
    kept = np.sum((markers[:, [0, 2, 3, 4, 5]] - observed[[0, 2, 3, 4, 5]]) ** 2, axis=(1, 2))
    for tracker, sigma in zip(runs, (0.02, 0.05)):
        expected = np.exp(-(kept - kept.min()) / (2 * sigma**2))
        np.testing.assert_allclose(tracker.weights, expected / expected.sum(), rtol=1e-9)


def test_the_object_s_motion_favours_manipulations_when_it_moves_and_the_others_when_still(models):
    """The motion term is discovery's definition of the classes: after a 2 cm push in five frames a
    manipulation particle scores the moving half-normal and an approach particle the still one (each mixed
    with the outlier share, divided by the window's five frames), so the manipulation gains; a still
    object favours the approach; before five frames of history, with the object unseen, or off, it is 0."""
    body = BodyModel(models.marker_names_, TORSO_BASE)
    manipulation = next(cid for cid, c in models.classes_.items() if c.kind == "manipulation")
    approach = next(cid for cid, c in models.classes_.items() if c.kind == "approach")
    still_m, moving_m = 0.003, 0.01

    def term(path, still=still_m):
        tracker = ActionTracker(models, body, CAMERA, n_particles=2, object_still_m=still, object_moving_m=moving_m,
                                random_state=0)
        for position in path:
            tracker._see_object(position)
        return tracker._evidence.motion_log_likelihood(np.array([manipulation, approach]), np.zeros(2, bool))

    def expected(moved, scale):
        return np.log(0.9 * np.sqrt(2 / np.pi) / scale * np.exp(-0.5 * (moved / scale) ** 2) + 0.1 / 0.3) / 5

    push = [np.array([0.004 * k, 0.0, 0.025]) for k in range(6)]
    moving = term(push)
    np.testing.assert_allclose(moving, [expected(0.02, moving_m), expected(0.02, still_m)])
    assert moving[0] > moving[1]
    still = term([push[0]] * 6)
    np.testing.assert_allclose(still, [expected(0.0, moving_m), expected(0.0, still_m)])
    assert still[1] > still[0]
    np.testing.assert_array_equal(term(push[:5]), 0.0)
    np.testing.assert_array_equal(term(push, still=None), 0.0)
    np.testing.assert_array_equal(term([*push[:5], None]), 0.0)


def test_same_seed_same_track(models, reach):
    _, _, movement = reach
    body = BodyModel(models.marker_names_, TORSO_BASE)
    runs = []
    for _ in range(2):
        tracker = ActionTracker(models, body, CAMERA, n_particles=50, random_state=3)
        runs.append(np.array([tracker.step(G).markers for G in images(body, movement[:40])]))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_systematic_resampling_keeps_heavy_particles(models):
    body = BodyModel(models.marker_names_, TORSO_BASE)
    tracker = ActionTracker(models, body, CAMERA, n_particles=10, random_state=0)
    tracker.end = np.arange(30, dtype=float).reshape(10, 3)
    weights = np.zeros(10)
    weights[[2, 7]] = [0.7, 0.3]
    tracker._resample(weights)
    kept = tracker.end[:, 0] / 3
    assert np.sum(kept == 2) == 7 and np.sum(kept == 7) == 3
    np.testing.assert_allclose(tracker.weights, 0.1)


def test_tracker_bad_input(models):
    body = BodyModel(models.marker_names_, TORSO_BASE)
    with pytest.raises(InvalidInputError, match="n_particles"):
        ActionTracker(models, body, CAMERA, n_particles=0)
    with pytest.raises(InvalidInputError, match="markers"):
        ActionTracker(models, BodyModel(("shoulder", "elbow", "wrist", "index_tip", "index_knuckle", "thumb_tip",
                                         "extra"), TORSO_BASE), CAMERA)
    tracker = ActionTracker(models, body, CAMERA, n_particles=5)
    with pytest.raises(InvalidInputError, match=r"\(240, 320\)"):
        tracker.step(np.zeros((10, 10), np.float32))
    with pytest.raises(InvalidInputError, match="one edge image per camera"):
        tracker.step([np.zeros((240, 320), np.float32)] * 2)
    with pytest.raises(InvalidInputError, match=r"finite values in \[0, 1\]"):
        tracker.step(np.full((240, 320), np.nan, np.float32))
    with pytest.raises(InvalidInputError, match="foreground mask must be"):
        tracker.step(np.zeros((240, 320), np.float32), np.zeros((24, 32), np.float32))
    for bad in (np.zeros(2), np.array([0.0, np.nan, 0.0])):
        with pytest.raises(InvalidInputError, match="object_position"):
            tracker.step(np.zeros((240, 320), np.float32), object_position=bad)
    with pytest.raises(InvalidInputError, match="silhouette_sigma"):
        ActionTracker(models, body, CAMERA, silhouette_sigma=0.0)
    for still, moving in ((0.0, 0.01), (0.003, -1.0)):
        with pytest.raises(InvalidInputError, match="object_still_m"):
            ActionTracker(models, body, CAMERA, object_still_m=still, object_moving_m=moving)
    with pytest.raises(InvalidInputError, match=r"\(6, 3\)"):
        tracker.step_markers(np.zeros((5, 3)))
    with pytest.raises(InvalidInputError, match="sigma_m"):
        tracker.step_markers(np.zeros((6, 3)), sigma_m=0.0)
    with pytest.raises(InvalidInputError, match="object_position"):
        tracker.step_markers(np.zeros((6, 3)), object_position=np.zeros(2))


def test_mean_poses_refuses_states_off_the_chain_and_misshapen_effects():
    model = load_default_models().classes_[0]
    k = model.phmm.n_states
    phi = np.tile(model.centre, (2, 1))
    ends = mean_poses(model, np.array([0.0, k - 1.0]), phi, 6)
    middle = mean_poses(model, np.array([0.5]), phi[:1], 6)
    first_two = mean_poses(model, np.array([0.0, 1.0]), phi, 6)
    assert ends.shape == (2, 18) and np.allclose(middle[0], first_two.mean(axis=0))  # halfway between two means
    for states, effects in (([k - 0.5], phi[:1]), ([-0.1], phi[:1]), ([0.0, 1.0], phi[:1])):
        with pytest.raises(InvalidInputError):
            mean_poses(model, np.array(states), effects, 6)


def _depth_image(body, pose, camera) -> np.ndarray:
    """A depth image of one body: each pixel its limbs cover takes the near-surface depth of the nearest limb
    axis point, NaN elsewhere: what a depth camera sees of the body alone."""
    v, u = np.mgrid[0:camera.height, 0:camera.width]
    pixels = np.stack([u.ravel(), v.ravel()], axis=1).astype(float)
    bodies = body.project(pose[None], camera)
    axis = body.interior(bodies)[0]
    surface = body.surface_depths(bodies)[0]
    covered = body.covers(bodies, pixels, body.limbs)[0]
    nearest = np.argmin(np.linalg.norm(pixels[covered, None] - axis[None], axis=2), axis=1)
    depth = np.full(len(pixels), np.nan)
    depth[covered] = surface[nearest]
    return depth.reshape(camera.height, camera.width)


def test_depth_term_prefers_the_true_pose_and_tells_depth_apart(models, reach):
    """A pose moved 5 cm along the camera's ray projects almost where the true one does, so the edges barely
    tell them apart; the depth image does. The misfit of the true pose is near 0, and the term adds to the
    log-likelihood with its sigma."""
    _, _, movement = reach
    body = BodyModel(models.marker_names_, TORSO_BASE)
    tracker = ActionTracker(models, body, CAMERA, n_particles=3, random_state=0)
    t = len(movement) * 3 // 4
    true = movement[t]
    ray = true[2] - np.asarray(CAMERA.eye)
    along_ray = true + 0.05 * ray / np.linalg.norm(ray)
    poses = np.stack([true, along_ray, true + [0.0, 0.05, 0.0]])
    D = _depth_image(body, true, CAMERA)
    misfit = depth_misfit(body, body.project(poses, CAMERA), D, CAMERA)
    assert misfit[0] < 1e-4 and misfit[1] > 1e-3 and misfit[2] > misfit[0]
    G = next(iter(images(body, movement[t:t + 1])))
    np.testing.assert_allclose(log_likelihood(tracker, poses, [G]) - log_likelihood(tracker, poses, [G], None, [D]),
                               misfit / (2 * tracker.depth_sigma_m**2))
    with pytest.raises(InvalidInputError, match="depths > 0"):
        tracker.step(G, depth=np.zeros((CAMERA.height, CAMERA.width)))


def test_depth_weighs_the_pose_estimate_and_leaves_the_filter_to_the_colour_images(models, reach):
    """By default the depth images tilt the pose estimate only: the same seed with and without them gives the same
    class posterior every frame, bit for bit (the filter reads the colour images alone), and estimates nearer the
    true reach (the body in front of a wall: a limb posed off the body meets the wall's depth);
    ``depth_weighs="filter"`` puts the depth term into every particle's weight, and its filter's classes differ. A
    role not offered is refused."""
    _, _, movement = reach
    body = BodyModel(models.marker_names_, TORSO_BASE)
    edges = list(images(body, movement))
    depths = [np.nan_to_num(_depth_image(body, pose, CAMERA), nan=2.0) for pose in movement]  # a wall 2 m behind
    runs = {}
    for name, depth, role in (("colour", None, "pose"), ("pose", depths, "pose"), ("filter", depths, "filter")):
        tracker = ActionTracker(models, body, CAMERA, n_particles=200, random_state=4, depth_weighs=role)
        runs[name] = [tracker.step(G, depth=None if depth is None else depth[t]) for t, G in enumerate(edges)]
    for colour, tilted_frame in zip(runs["colour"], runs["pose"]):
        assert colour.class_probabilities == tilted_frame.class_probabilities
    assert any(a.class_probabilities != b.class_probabilities for a, b in zip(runs["colour"], runs["filter"]))

    def error(frames):
        return np.sqrt(np.mean([np.sum((f.markers - pose) ** 2) for f, pose in zip(frames, movement)]))

    assert error(runs["pose"]) < error(runs["colour"])
    for bad in ("evidence", None, 1):
        with pytest.raises(InvalidInputError, match="depth_weighs"):
            ActionTracker(models, body, CAMERA, depth_weighs=bad)


def test_surface_depths_are_the_limb_axes_distance_along_the_view_less_the_radius(models, reach):
    """Cross-check against the camera's geometry written out: the axis points between each limb's two
    markers, their distance from the eye along the unit view direction, less the capsule's radius."""
    _, _, movement = reach
    body = BodyModel(models.marker_names_, TORSO_BASE)
    pose = movement[len(movement) // 2]
    forward = np.subtract(CAMERA.target, CAMERA.eye)
    forward /= np.linalg.norm(forward)
    expected = []
    for k in body.limbs:
        capsule = body.capsules[k]
        start, end = (pose[MARKERS.index(name)] for name in (capsule.start, capsule.end))
        for t in np.linspace(0.0, 1.0, body.points_per_side):
            expected.append((start + t * (end - start) - np.asarray(CAMERA.eye)) @ forward - capsule.radius)
    np.testing.assert_allclose(body.surface_depths(body.project(pose[None], CAMERA))[0], expected, atol=1e-12)


def test_the_object_s_place_tells_the_pieces_of_a_push_apart(models):
    """The place term: a push piece whose learned displacement carries the block to where it is seen scores
    0, the opposite piece the quadratic misfit, capped at 5 cm; an approach keeps the block where its class
    began; the term is 0 when the block is not seen or the term is off (the default)."""
    from hoap_actions.tracking.object_evidence import OBJECT_PLACE_CAP_M, ObjectEvidence
    from hoap_actions.tracking.tracking_models import TrackingModels

    tracking = TrackingModels.from_action_models(models)
    evidence = ObjectEvidence(tracking, place_m=0.02)
    shifts = {cid: evidence.displacement[cid] for cid in evidence.manipulations}
    short = [cid for cid in shifts if np.linalg.norm(shifts[cid]) < 0.04]  # pieces under 4 cm: within the cap
    right = max(short, key=lambda cid: shifts[cid][0])  # the piece that pushes furthest along +x
    left = min(short, key=lambda cid: shifts[cid][0])
    approach = next(cid for cid, c in tracking.classes.items() if c.kind == "approach")
    began = np.zeros((3, 3))
    evidence.see(np.array([*shifts[right][:2], 0.025]))
    resting = np.array([True, True, False])  # finished pieces: the whole displacement
    term = evidence.place_log_likelihood(np.array([right, left, approach]), np.zeros(3), resting, began)
    gap_left = np.sum((shifts[left][:2] - shifts[right][:2]) ** 2)
    gap_still = np.sum(shifts[right][:2] ** 2)
    misfit = np.minimum([gap_left, gap_still], OBJECT_PLACE_CAP_M**2)
    np.testing.assert_allclose(term, [0.0, *(-misfit / (2 * 0.02**2))])
    assert term[0] > term[1] and term[0] > term[2]
    at_start = evidence.place_log_likelihood(np.array([right]), np.zeros(1), np.zeros(1, bool), began[:1])
    np.testing.assert_allclose(at_start, term[2:])  # at its first state a piece has not moved the block yet
    evidence.see(None)
    np.testing.assert_array_equal(evidence.place_log_likelihood(np.array([right]), np.zeros(1), resting[:1],
                                                                began[:1]), 0.0)
    off = ObjectEvidence(tracking)
    off.see(np.zeros(3))
    np.testing.assert_array_equal(off.place_log_likelihood(np.array([right]), np.zeros(1), resting[:1], began[:1]),
                                  0.0)
    body = BodyModel(models.marker_names_, TORSO_BASE)
    for bad in (0.0, -0.01, np.nan):
        with pytest.raises(InvalidInputError, match="object_place_m"):
            ActionTracker(models, body, CAMERA, object_place_m=bad)


def test_an_approach_goal_is_drawn_from_a_training_approach_s_end_at_the_seen_block(models):
    """With the models' approach ends, a goal drawn at the seen block is one of them moved to it (x, y from the
    block, the height as it was) with APPROACH_END_JITTER_M of jitter, each as often as it was trained; without
    them, the mean offset with the broad spread. Ends that are not finite (n, 3) rows are refused, and models
    learned with object poses but without them warn."""
    import copy
    import dataclasses

    from hoap_actions.errors import MissingModelPartWarning
    from hoap_actions.tracking.action_tracker import APPROACH_END_JITTER_M, OBJECT_END_SPREAD_M
    from hoap_actions.tracking.tracking_models import TrackingModels

    tracking = TrackingModels.from_action_models(models)
    ends = np.array([[0.03, -0.02, 0.08], [-0.06, 0.0, 0.07], [-0.06, 0.0, 0.07]])
    body = BodyModel(models.marker_names_, TORSO_BASE)
    tracker = ActionTracker(dataclasses.replace(tracking, approach_ends=ends), body, CAMERA, random_state=0)
    tracker._object = np.array([0.1, 0.2, 0.025])
    drawn = tracker._end_at_object(6000)
    centres = np.array([[0.13, 0.18, 0.08], [0.04, 0.2, 0.07]])
    nearest = np.argmin(np.linalg.norm(drawn[:, None] - centres[None], axis=2), axis=1)
    assert abs(np.mean(nearest == 1) - 2 / 3) < 0.03  # the second end was trained twice
    for k, centre in enumerate(centres):
        mine = drawn[nearest == k]
        np.testing.assert_allclose(mine.mean(axis=0), centre, atol=0.0005)
        np.testing.assert_allclose(mine.std(axis=0), APPROACH_END_JITTER_M, rtol=0.1)
    broad = ActionTracker(dataclasses.replace(tracking, approach_ends=None), body, CAMERA, random_state=0)
    broad._object = tracker._object
    np.testing.assert_allclose(broad._end_at_object(6000).std(axis=0), OBJECT_END_SPREAD_M, rtol=0.1)
    for wrong in (ends[:, :2], np.empty((0, 3)), np.where(ends > 0.05, np.nan, ends)):
        with pytest.raises(InvalidInputError, match="approach_ends"):
            dataclasses.replace(tracking, approach_ends=wrong)
    older = copy.copy(models)
    older.approach_ends_ = None
    with pytest.warns(MissingModelPartWarning, match="no approach ends"):
        assert TrackingModels.from_action_models(older).approach_ends is None


def test_an_approach_s_end_is_read_from_the_particles_still_in_an_approach():
    """The approach-end figure reads the approach classes' own end (weighted by their probabilities), not the
    mean over particles that began a manipulation and estimate where the block goes; with no particle in an
    approach, the mean over all."""
    from hoap_actions.tracking.action_tracker import TrackedFrame
    from hoap_actions.tracking.episode import TrackResult

    target = np.array([0.1, 0.0, 0.08])
    reach, block = target + [0.01, 0.0, 0.0], np.array([0.3, 0.1, 0.025])

    def frame(p_approach: float) -> TrackedFrame:
        ends = {0: reach, 7: block} if p_approach > 0 else {7: block}
        probabilities = {0: p_approach, 7: 1.0 - p_approach} if p_approach > 0 else {7: 1.0}
        return TrackedFrame(0, 0, np.zeros(6), probabilities, p_approach * reach + (1 - p_approach) * block,
                            np.zeros(3), 0.0, np.zeros((6, 3)), 0.0, class_ends=ends)

    for p_approach, error in ((1.0, 0.01), (0.3, 0.01), (0.0, np.linalg.norm(block - target))):
        result = TrackResult([frame(1.0), frame(p_approach)], np.zeros((2, 6, 3)), np.array([0, 0]),
                             [(0, 2, target)], MARKERS, 10, 1.0, TORSO_BASE, True,
                             kinds={0: "approach", 7: "manipulation"})
        summary = result.summary()
        assert summary["phi_error_m"] == pytest.approx(error)
        assert summary["approaches_converged"] == (1 if error < 0.02 else 0)


def test_with_far_leaps_a_share_of_particles_leaps_anywhere_in_the_rest_of_its_chain(models):
    """``far_leap_share``: one propagation from the start of each long chain; beyond the learned pace the far
    leapers' advance is uniform over the rest of the chain (its mean half of it, its largest near all of it),
    about that share of the manipulation and remove particles leap further than an ordinary leap can, approach
    particles never leap; shares outside [0, 1] are refused."""
    body = BodyModel(models.marker_names_, TORSO_BASE)
    tracker = ActionTracker(models, body, CAMERA, n_particles=40000, random_state=1, far_leap_share=0.2)
    tracked = tracker.models.classes
    long_classes = sorted(c for c in tracked if tracked[c].phmm.n_states >= 30)
    tracker.class_id = np.resize(long_classes, tracker.n_particles)
    sizes = np.array([tracked[c].phmm.n_states for c in tracker.class_id])
    tracker.state = np.zeros(tracker.n_particles)
    tracker._propagate()
    rates = np.array([1.0 - tracked[c].phmm.transmat_[0, 0] for c in tracker.class_id])
    advance = (tracker.state - rates * tracker.speed) / (sizes - 1)  # share of the chain, beyond the pace
    approach = np.array([tracked[c].kind == "approach" for c in tracker.class_id])
    assert np.any(approach) and np.all(np.abs(advance[approach]) < 1e-9)
    others = advance[~approach]
    far = others > LEAP_CHAIN_SHARE * 1.05  # no ordinary leap goes this far
    expected_far = 0.2 * (1 - LEAP_CHAIN_SHARE)  # a far leap shorter than an ordinary one's reach is not told apart
    assert abs(np.mean(far) - expected_far) < 4 * np.sqrt(expected_far * (1 - expected_far) / others.size)
    assert others.max() > 0.97 and np.all(tracker.state <= sizes - 1)
    for wrong in (-0.1, 1.5, True, "0.1"):
        with pytest.raises(InvalidInputError, match="far_leap_share"):
            ActionTracker(models, body, CAMERA, far_leap_share=wrong)


def test_a_block_hidden_in_part_from_the_start_draws_the_goals_until_it_is_seen_whole(models, reach):
    """A block that something in front of the camera hides in part from the first frame (every sighting partial)
    still draws the reach's goal towards it: the end is nearer the truth than with no sighting, for each of three
    seeds. Partial sightings stand in only until a first whole one: after it they leave the goals' block where it
    was seen whole (a hand over the block hides it)."""
    approach, phi, movement = reach
    body = BodyModel(models.marker_names_, TORSO_BASE)
    edges = list(images(body, movement))
    for seed in range(3):
        errors = []
        for sighting in (None, "partial"):
            tracker = ActionTracker(models, body, CAMERA, n_particles=200, random_state=seed)
            block = np.r_[phi[3:5] - tracker.hand_from_object[:2], 0.025]
            frames = [tracker.step(G, object_position=None if sighting is None else block, object_whole=False)
                      for G in edges]
            errors.append(np.linalg.norm(frames[-1].end_mean[:2] - phi[3:5]))
        assert errors[1] < errors[0]
    tracker = ActionTracker(models, body, CAMERA, n_particles=50, random_state=0)
    partly, whole, later = (np.array([x, 0.1, 0.025]) for x in (0.10, 0.12, 0.15))
    tracker.step(edges[0], object_position=partly, object_whole=False)
    np.testing.assert_array_equal(tracker.object_seen, partly)
    tracker.step(edges[1], object_position=whole, object_whole=True)
    tracker.step(edges[2], object_position=later, object_whole=False)
    np.testing.assert_array_equal(tracker.object_seen, whole)
