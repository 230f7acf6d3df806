"""ActionModels: learning from discovered classes, recognition, grammar decoding, synthesis, the models directory."""

from __future__ import annotations

import dataclasses
import json
import shutil
import warnings

import numpy as np
import pytest

from hoap_actions.apps.cli import main
from hoap_actions.errors import DataExistsError, DataFileError, ExtrapolationWarning, InvalidInputError, NotFittedError
from hoap_actions.primitives.discovery.estimator import PrimitiveDiscovery
from hoap_actions.primitives.labels import runs
from hoap_actions.primitives.models.action_models import ActionModels
from hoap_actions.primitives.models.class_models import marker_features
from hoap_actions.primitives.models.models_directory import MANIFEST


def pieces_of(demos, discovery, demo):
    return [demos[demo].H[start:end] for _, start, end in discovery.segmentations_[demo]]


def test_one_model_per_discovered_class_and_the_grammar_of_their_order(small):
    demos, discovery, models, _ = small
    assert sorted(models.classes_) == sorted(c.primitive_id for c in discovery.classes_)
    assert {m.kind for m in models.classes_.values()} == {"approach", "manipulation", "remove"}
    for sequence in discovery.segmentations_:
        assert models.grammar_.is_grammatical([pid for pid, *_ in sequence])


def test_training_pieces_are_recognised_as_their_class_alone_and_through_the_grammar(small):
    demos, discovery, models, _ = small
    for demo, segmentation in enumerate(discovery.segmentations_):
        truth = [pid for pid, *_ in segmentation]
        pieces = pieces_of(demos, discovery, demo)
        assert [models.recognize(p).class_id for p in pieces] == truth
        assert [r.class_id for r in models.decode_segments(pieces)] == truth


def modelled(models, class_id, phi):
    """The part of ``phi`` a class's PHMM represents: its projection on the class's effect directions
    (few training segments give few directions)."""
    model = models.classes_[class_id]
    return model.full_phi(model.reduced_phi(phi))


def test_recognised_phi_is_the_segments_effect(small):
    """On a training piece, the estimated (initial, final) location is the one discovery measured."""
    demos, discovery, models, _ = small
    for cls in discovery.classes_:
        for segment in cls.segments:
            rec = models.recognize(demos[segment.demo].H[segment.start:segment.end])
            assert rec.class_id == cls.primitive_id
            assert np.abs(rec.phi - modelled(models, cls.primitive_id, segment.phi)).max() < 0.01  # m


def test_synthesized_movement_of_a_class_follows_its_demonstration(small):
    demos, discovery, models, _ = small
    approach = next(c for c in discovery.classes_ if c.kind == "approach")
    segment = approach.segments[0]
    phi = modelled(models, approach.primitive_id, segment.phi)
    made = models.synthesize(approach.primitive_id, phi)
    assert made.shape[1:] == (6, 3)
    hand = discovery.hand_marker
    # the synthesised hand starts and ends at the effect's locations (within 1 cm) and lasts as long
    # as the class's demonstrations do on average
    assert np.linalg.norm(made[0, hand] - phi[:3]) < 0.01
    assert np.linalg.norm(made[-1, hand] - phi[3:]) < 0.01
    mean_frames = np.mean([s.end - s.start for s in approach.segments])
    assert abs(len(made) - mean_frames) <= 0.1 * mean_frames


def test_marker_features_append_the_displacement_over_a_tenth_of_a_second():
    t = np.arange(50)[:, None, None] * np.ones((1, 6, 3))
    H = 0.01 * t  # every coordinate moves 1 cm per frame
    X = marker_features(H, fps=100.0)
    assert X.shape == (50, 36)
    np.testing.assert_allclose(X[:, 18:], 0.1)  # 10 frames of 1 cm
    np.testing.assert_array_equal(marker_features(H, 100.0, velocity=False), H.reshape(50, 18))


def test_save_and_load_give_the_same_recognitions(small, tmp_path):
    demos, discovery, models, _ = small
    path = tmp_path / "models"
    models.save(path)
    loaded = ActionModels.load(path)
    assert loaded.get_params() == models.get_params()
    piece = pieces_of(demos, discovery, 1)[1]
    a, b = models.recognize(piece), loaded.recognize(piece)
    assert a.class_id == b.class_id and a.log_likelihoods == b.log_likelihoods
    np.testing.assert_array_equal(a.phi, b.phi)
    with pytest.raises(DataExistsError):
        models.save(path)


@pytest.fixture
def saved(small, tmp_path):
    path = tmp_path / "models"
    small[2].save(path)
    return path


def edit_manifest(path, change):
    manifest = json.loads((path / MANIFEST).read_text())
    change(manifest)
    (path / MANIFEST).write_text(json.dumps(manifest))


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda p: shutil.rmtree(p), "no models directory"),
        (lambda p: (p / MANIFEST).unlink(), "manifest.json is missing"),
        (lambda p: (p / "class_1.npz").unlink(), "class_1.npz does not exist"),
        (lambda p: (p / "grammar.json").unlink(), "grammar"),
        (lambda p: edit_manifest(p, lambda m: m.update(format_version=99)), "format_version 99"),
        (lambda p: edit_manifest(p, lambda m: m.update(fps=-1)), "entry fps must be a positive number"),
        (lambda p: edit_manifest(p, lambda m: m["params"].update(state_fraction=7)), "entry params: state_fraction"),
        (lambda p: edit_manifest(p, lambda m: m["params"].update(colour="red")), "entry params: .*accepted"),
        (lambda p: edit_manifest(p, lambda m: m["classes"][0].update(exit_probability=0)), "exit_probability must be"),
        (lambda p: edit_manifest(p, lambda m: m.update(kind="Other")), "not a ActionModels file"),
        (lambda p: edit_manifest(p, lambda m: m["classes"].pop()), "do not match the discovery"),
        (lambda p: edit_manifest(p, lambda m: m["classes"][0].update(effect_centre=[0, 1])), "effect_centre must be"),
        (lambda p: edit_manifest(p, lambda m: m["classes"][0].update(effect_basis=[[0.0]] * 6)), "effect directions"),
        (lambda p: (p / MANIFEST).write_text("{nonsense"), "not a readable JSON ActionModels manifest"),
    ],
    ids=["missing-dir", "no-manifest", "missing-class", "no-grammar", "other-version", "bad-fps", "bad-params",
         "unknown-param", "bad-exit", "other-kind",
         "class-dropped", "bad-centre", "basis-mismatch", "not-json"],
)
def test_load_rejects_missing_partial_other_version_and_edited_directories(saved, damage, message):
    damage(saved)
    with pytest.raises(DataFileError, match=message):
        ActionModels.load(saved)


def test_bad_inputs_name_what_is_accepted(small):
    demos, discovery, models, _ = small
    with pytest.raises(InvalidInputError, match="phi must be 6 finite numbers"):
        models.synthesize(0, np.zeros(3))
    with pytest.raises(InvalidInputError, match="phi must be 6 finite numbers"):
        models.synthesize(0, np.full(6, np.nan))
    with pytest.raises(InvalidInputError, match=r"no class 99; classes: \[0, 1"):
        models.synthesize(99, np.zeros(6))
    with pytest.raises(InvalidInputError, match=r"a movement must be \(T, 6, 3\)"):
        models.recognize(np.zeros((40, 5, 3)))
    with pytest.raises(InvalidInputError, match="finite"):
        models.recognize(np.full((40, 6, 3), np.nan))
    with pytest.raises(NotFittedError, match="ActionModels is not fitted"):
        ActionModels().recognize(np.zeros((40, 6, 3)))
    with pytest.raises(InvalidInputError, match="state_fraction must be a number in"):
        ActionModels(state_fraction=0).fit(np.zeros((10, 18)), [10], discovery, 100.0)
    with pytest.raises(InvalidInputError, match="discovery was fitted on 4 demonstrations but H holds 1"):
        ActionModels().fit(np.zeros((10, 18)), [10], discovery, 100.0)
    with pytest.raises(InvalidInputError, match="mean_model must be 'linear' or 'tps'"):
        ActionModels(mean_model="cubic").fit(np.zeros((10, 18)), [10], discovery, 100.0)


def test_bending_mean_models_reach_every_class_and_survive_a_round_trip(small, tmp_path):
    demos, discovery, _, _ = small
    lengths = [e.T for e in demos]
    H = np.concatenate([e.H.reshape(e.T, -1) for e in demos])
    bent = ActionModels(mean_model="tps", smoothing=0.5).fit(H, lengths, discovery, demos.fps, demos.marker_names)
    modelled_classes = [c for c in bent.classes_.values() if c.phmm.phi_dim_ > 0]
    assert modelled_classes and all(c.phmm.mean_model == "tps" and c.phmm.V_.shape[2] > 0 for c in modelled_classes)
    bent.save(tmp_path / "bent")
    again = ActionModels.load(tmp_path / "bent")
    assert again.get_params() == bent.get_params()
    piece = demos[0].H[discovery.segmentations_[0][0][1]:discovery.segmentations_[0][0][2]]
    assert again.recognize(piece).class_id == bent.recognize(piece).class_id


def test_phi_far_outside_the_demonstrations_warns(small):
    demos, discovery, models, _ = small
    approach = next(c for c in discovery.classes_ if c.kind == "approach")
    near = modelled(models, approach.primitive_id, approach.segments[0].phi)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a demonstrated effect: no warning
        models.synthesize(approach.primitive_id, near)
    far = near + np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0])  # the reach's end 1 m further away
    with pytest.warns(ExtrapolationWarning,
                      match=r"final x -?\d\.\d+ m, demonstrated -?\d\.\d+\.\.-?\d\.\d+ m") as caught:
        models.synthesize(approach.primitive_id, far)
    assert len(caught) == 1  # said once, in the full phi's terms
    highest_end = max(segment.phi[5] for segment in approach.segments)
    above = near + np.array([0.0, 0.0, 0.0, 0.0, 0.0, highest_end + 1.0 - near[5]])  # 1 m above every reach's end
    with pytest.warns(ExtrapolationWarning, match="final z"):
        models.synthesize(approach.primitive_id, above)


def test_learn_command_writes_the_models_directory_and_refuses_to_replace_it(small, tmp_path, capsys):
    demos, discovery, models, path = small
    out = tmp_path / "models"
    assert main(["learn", "--demos", str(path), "--out", str(out)]) == 0
    assert "5 classes" in capsys.readouterr().out
    learned = ActionModels.load(out)
    assert sorted(learned.classes_) == sorted(models.classes_)
    piece = pieces_of(demos, discovery, 0)[1]
    assert learned.recognize(piece).log_likelihoods == models.recognize(piece).log_likelihoods  # same fit
    assert main(["learn", "--demos", str(path), "--out", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err


def test_learn_command_takes_a_discover_folder_only_of_the_same_demonstrations(small, tmp_path, capsys):
    _, _, _, path = small
    assert main(["discover", "--demos", str(path), "--out", str(tmp_path / "found")]) == 0
    assert main(["learn", "--demos", str(path), "--out", str(tmp_path / "m"),
                 "--discovery", str(tmp_path / "found")]) == 0
    assert main(["learn", "--demos", str(path), str(path), "--out", str(tmp_path / "m2"),
                 "--discovery", str(tmp_path / "found")]) == 2
    assert "fitted on 4 demonstrations, not on these 8" in capsys.readouterr().err
    assert not (tmp_path / "m2").exists()


def test_the_merging_chosen_on_the_command_line_is_the_discovery_s_and_a_mismatch_is_refused(small, tmp_path, capsys):
    _, _, _, path = small
    for merging in ("fold", "agglomerative"):
        assert main(["discover", "--demos", str(path), "--out", str(tmp_path / merging), "--merging", merging]) == 0
        assert PrimitiveDiscovery.load(tmp_path / merging / "model.json").merging == merging
    assert main(["learn", "--demos", str(path), "--out", str(tmp_path / "m"), "--discovery", str(tmp_path / "fold"),
                 "--merging", "agglomerative"]) == 2
    assert "merged with 'fold', not the 'agglomerative' asked for" in capsys.readouterr().err
    assert not (tmp_path / "m").exists()
    assert main(["learn", "--demos", str(path), "--out", str(tmp_path / "m"), "--discovery", str(tmp_path / "fold"),
                 "--merging", "fold"]) == 0
    with pytest.raises(SystemExit) as exit_info:
        main(["learn", "--demos", str(path), "--out", str(tmp_path / "m3"), "--merging", "greedy"])
    assert exit_info.value.code == 2 and "merging must be one of fold, agglomerative" in capsys.readouterr().err


def test_whole_training_movements_are_cut_and_classified_from_the_markers_alone(small):
    """Connected recognition on the training episodes with a manipulation: their class sequences, and
    most frames. (The approach-only episode is one long approach to discovery, whose object never
    moves, though the hand reaches and withdraws.)"""
    demos, discovery, models, _ = small
    right = total = 0
    for demo, segmentation in enumerate(discovery.segmentations_):
        if len(segmentation) == 1:
            continue
        decoded = models.decode(demos[demo].H)
        assert [s.class_id for s in decoded] == [pid for pid, *_ in segmentation]
        assert decoded[0].start == 0 and decoded[-1].end == demos[demo].T
        truth = np.concatenate([np.full(end - start, pid) for pid, start, end in segmentation])
        predicted = np.concatenate([np.full(s.end - s.start, s.class_id) for s in decoded])
        right, total = right + np.sum(truth == predicted), total + len(truth)
    assert right / total > 0.85


def test_recognize_command_gives_the_same_figures_with_one_or_two_workers(small, tmp_path, capsys):
    demos, discovery, models, path = small
    models.save(tmp_path / "models")
    reports = []
    for jobs in ("1", "2"):
        out = tmp_path / f"r{jobs}.json"
        assert main(["recognize", "--demos", str(path), "--models", str(tmp_path / "models"), "--json", str(out),
                     "--jobs", jobs, "--no-oracle"]) == 0
        reports.append(json.loads(out.read_text()))
    keys = ("frame_accuracy", "segment_accuracy", "edit_score", "phi_error_median_m", "episodes", "segments")
    assert {k: reports[0][k] for k in keys} == {k: reports[1][k] for k in keys}
    assert reports[0]["oracle_cut_accuracy"] is None
    assert "frame accuracy" in capsys.readouterr().out
    assert main(["recognize", "--demos", str(path), "--models", str(tmp_path / "nothing")]) == 2
    assert "no models directory" in capsys.readouterr().err


def test_a_recording_of_other_markers_or_rate_is_refused(small):
    import dataclasses

    from hoap_actions.primitives.pipelines.recognize import recognize_recording

    demos, _, models, _ = small
    other_markers = dataclasses.replace(demos, marker_names=tuple(f"m{i}" for i in range(6)))
    with pytest.raises(InvalidInputError, match="recognise recordings of the same kind"):
        recognize_recording(models, other_markers)
    with pytest.raises(InvalidInputError, match="at 50.0 fps"):
        recognize_recording(models, dataclasses.replace(demos, fps=50.0))
    with pytest.raises(InvalidInputError, match="jobs must be an int >= 1"):
        recognize_recording(models, demos, jobs=0)


@pytest.fixture(scope="module")
def with_actions(small):
    demos, discovery, _, path = small
    lengths = [e.T for e in demos]
    H = np.concatenate([e.H.reshape(e.T, -1) for e in demos])
    O = np.concatenate([e.O for e in demos])
    return ActionModels().fit(H, lengths, discovery, demos.fps, demos.marker_names, O=O)


def test_the_action_level_has_whole_approach_manipulation_and_remove_models(small, with_actions):
    demos, discovery, _, _ = small
    kinds = sorted(m.kind for m in with_actions.actions_.values())
    assert kinds == ["approach", "manipulation", "manipulation", "manipulation", "remove"]  # push, move, rotate
    lifts = {a: with_actions.action_lifts_[a] for a, m in with_actions.actions_.items() if m.kind == "manipulation"}
    carry = max(lifts, key=lifts.get)  # the move lifts the block; the push and the rotation do not
    move_episode = next(i for i, e in enumerate(demos) if e.ground_truth.action == "move")
    segments = discovery.segmentations_[move_episode]
    pieces = [(a, b) for pid, a, b in segments if discovery.primitive_kinds_[pid] == "manipulation"]
    start, end = pieces[0][0], pieces[-1][1]
    O = demos[move_episode].O
    phi = np.r_[O[start, :3], O[end - 1, :3]]
    made = with_actions.synthesize_action(carry, phi, n_frames=end - start)
    shown = demos[move_episode].H[start:end]
    hand = discovery.hand_marker
    # trained on this one carry, the whole action reproduces it: the hand's path within 1 cm
    assert np.median(np.linalg.norm(made[:, hand] - shown[:, hand], axis=1)) < 0.01
    assert lifts[carry] > 0.02 and sorted(lifts.values())[-2] < 0.01  # m


def test_every_class_belongs_to_the_whole_action_of_its_kind(small, with_actions):
    demos, discovery, _, _ = small
    assert set(with_actions.action_of_class_) == set(with_actions.classes_)
    for cid, action in with_actions.action_of_class_.items():
        assert with_actions.actions_[action].kind == with_actions.classes_[cid].kind
    for _demo, segments in enumerate(discovery.segmentations_):  # the pieces of one run share its action
        pieces = {with_actions.action_of_class_[pid] for pid, *_ in segments
                  if discovery.primitive_kinds_[pid] == "manipulation"}
        assert len(pieces) <= 1


def test_the_action_level_is_saved_and_loaded(with_actions, tmp_path):
    with_actions.save(tmp_path / "models")
    loaded = ActionModels.load(tmp_path / "models")
    assert (sorted(loaded.actions_) == sorted(with_actions.actions_)
            and loaded.action_lifts_ == with_actions.action_lifts_)
    assert loaded.action_of_class_ == with_actions.action_of_class_
    action = next(a for a, m in loaded.actions_.items() if m.kind == "approach")
    phi = loaded.actions_[action].centre
    np.testing.assert_array_equal(loaded.synthesize_action(action, phi), with_actions.synthesize_action(action, phi))
    manifest = json.loads((tmp_path / "models" / MANIFEST).read_text())
    manifest["actions"][0]["lift_m"] = "high"
    (tmp_path / "models" / MANIFEST).write_text(json.dumps(manifest))
    with pytest.raises(DataFileError, match="lift_m must be a number"):
        ActionModels.load(tmp_path / "models")


def test_models_without_an_action_level_say_how_to_get_one(small):
    _, _, models, _ = small
    assert models.actions_ == {} and models.action_of_class_ == {}
    with pytest.raises(InvalidInputError, match="no action level: fit them with the object poses O"):
        models.synthesize_action(0, np.zeros(6))


def test_whole_action_errors_score_each_run_by_its_action(small, with_actions):
    from hoap_actions.primitives.evaluation.synthesis import whole_action_errors

    demos, _, models, _ = small
    errors = whole_action_errors(with_actions, demos)  # the training runs themselves
    assert sum(e["runs"] for e in errors.values()) == 3  # the push, the move and the rotation
    carry = max(with_actions.action_lifts_, key=with_actions.action_lifts_.get)
    # on its own training run the carry is followed within 1 cm, closer than the straight line
    assert errors[carry]["model_m"][0] < 0.01 and errors[carry]["model_m"][0] < errors[carry]["baseline_m"][0]
    with pytest.raises(InvalidInputError, match="no action level"):
        whole_action_errors(models, demos)


def test_a_refit_does_not_keep_the_previous_fits_chained_hmm(small):
    demos, discovery, _, _ = small
    lengths = [e.T for e in demos]
    H = np.concatenate([e.H.reshape(e.T, -1) for e in demos])
    models = ActionModels(max_states=5).fit(H, lengths, discovery, demos.fps)
    first = models.chained()
    assert models.chained() is first  # built once per fit
    models.fit(H, lengths, discovery, demos.fps)
    assert models.chained() is not first


def test_time_stretched_copies_for_speed_augmentation():
    from hoap_actions.primitives.models.action_models import _stretch

    ramp = np.linspace(0.0, 1.0, 11)[:, None] * np.ones((1, 18))
    slow = _stretch(ramp, 1.5)
    assert slow.shape == (16, 18)  # 11 frames performed 1.5 times as long
    np.testing.assert_allclose(slow[:, 0], np.linspace(0.0, 1.0, 16))  # the same path, more frames
    with pytest.raises(InvalidInputError, match="speed_augmentation must be a tuple of time-stretch factors"):
        ActionModels(speed_augmentation=(1.0,))._check_params()
    with pytest.raises(InvalidInputError, match="speed_augmentation"):
        ActionModels(speed_augmentation=(3.0,))._check_params()


def test_speed_augmented_models_save_and_load(small, tmp_path):
    demos, discovery, _, _ = small
    H, lengths = demos.movement_data()
    models = ActionModels(speed_augmentation=(0.8, 1.25)).fit(H, lengths, discovery, demos.fps, demos.marker_names)
    models.save(tmp_path / "augmented")
    loaded = ActionModels.load(tmp_path / "augmented")
    assert loaded.get_params() == models.get_params() and loaded.speed_augmentation == (0.8, 1.25)
    piece = pieces_of(demos, discovery, 1)[1]
    assert loaded.recognize(piece).class_id == models.recognize(piece).class_id


def test_the_object_estimated_from_the_hand_is_parsed_into_each_training_piece_class(small, with_actions):
    demos, discovery, _, _ = small
    assert with_actions.grasp_offset_.shape == (3,) and np.all(np.isfinite(with_actions.grasp_offset_))
    voted = 0
    for demo, segmentation in enumerate(discovery.segmentations_):
        truth = [pid for pid, *_ in segmentation]
        votes = with_actions.object_votes(pieces_of(demos, discovery, demo), truth)
        if any(with_actions.classes_[c].kind == "manipulation" for c in truth):
            assert votes == truth
            voted += 1
        else:  # nothing moved the object: no vote
            assert votes is None
    assert voted == 3  # push, move and rotate


def a_manipulation_demo(small, with_actions):
    """Demonstration 1's pieces (approach, manipulation, remove), their true classes, each piece's
    recognition, and a manipulation class other than the true one."""
    demos, discovery, _, _ = small
    pieces = pieces_of(demos, discovery, 1)
    truth = [pid for pid, *_ in discovery.segmentations_[1]]
    other = next(c for c, m in with_actions.classes_.items() if m.kind == "manipulation" and c != truth[1])
    return pieces, truth, [with_actions.recognize(p) for p in pieces], other


def test_the_object_vote_decides_between_look_alike_pieces(small, with_actions):
    pieces, truth, recognitions, other = a_manipulation_demo(small, with_actions)
    tied = [dataclasses.replace(r, log_likelihoods={c: 0.0 for c in r.log_likelihoods}) for r in recognitions]
    votes = with_actions.object_votes(pieces, truth)
    assert [r.class_id for r in with_actions._decode(tied, votes)] == truth  # the vote breaks the tie
    wrong = [votes[0], other, votes[2]]
    assert with_actions._decode(tied, wrong)[1].class_id == other


def test_the_vote_reaches_a_class_whose_chain_is_longer_than_the_piece(small, with_actions):
    _, truth, recognitions, other = a_manipulation_demo(small, with_actions)
    # the piece as a brisker demonstrator's: too short for its class's chain (-inf), another class explains it
    scores = {c: -np.inf for c in recognitions[1].log_likelihoods} | {other: 0.0}
    recognitions[1] = dataclasses.replace(recognitions[1], log_likelihoods=scores)
    assert with_actions._decode(recognitions)[1].class_id == other
    try:  # a vote worth more than the penalty: the voted class wins although its chain cannot explain the piece
        with_actions.set_params(object_vote=2 * with_actions.unexplained_penalty)
        assert with_actions._decode(recognitions, truth)[1].class_id == truth[1]
    finally:
        with_actions.set_params(object_vote=ActionModels().object_vote)


def test_models_without_object_poses_or_with_the_vote_off_do_not_vote(small, with_actions):
    demos, discovery, models, _ = small
    pieces = pieces_of(demos, discovery, 1)
    truth = [pid for pid, *_ in discovery.segmentations_[1]]
    assert models.grasp_offset_ is None and models.object_votes(pieces, truth) is None
    assert with_actions.object_votes(pieces, truth) is not None
    try:
        assert with_actions.set_params(object_vote=0.0).object_votes(pieces, truth) is None
        with pytest.raises(InvalidInputError, match="object_vote must be a number"):
            with_actions.set_params(object_vote=-1.0)
        assert with_actions.object_vote == 0.0  # a refused value leaves the parameters as they were
        with pytest.raises(InvalidInputError, match="fit a new one to change"):
            with_actions.set_params(max_states=3)
        chained = with_actions.chained()
        assert with_actions.set_params(object_vote=500.0).chained() is chained  # not shaped by the vote
        rebuilt = with_actions.set_params(stay_weight=1.0).chained()
        np.testing.assert_allclose(rebuilt.log_stay, chained.log_stay / ActionModels().stay_weight)
    finally:
        with_actions.set_params(object_vote=ActionModels().object_vote, stay_weight=ActionModels().stay_weight)


def test_the_grasp_offset_is_saved_checked_and_absent_from_older_directories(with_actions, tmp_path):
    path = tmp_path / "models"
    with_actions.save(path)
    np.testing.assert_array_equal(ActionModels.load(path).grasp_offset_, with_actions.grasp_offset_)
    edit_manifest(path, lambda m: m.update(grasp_offset=[0.0, float("nan"), 0.0]))
    with pytest.raises(DataFileError, match="entry grasp_offset must be"):
        ActionModels.load(path)
    edit_manifest(path, lambda m: (m.update(format_version=2), m.pop("grasp_offset")))
    assert ActionModels.load(path).grasp_offset_ is None


def test_the_object_parse_of_a_whole_movement_follows_the_objects_own_classes(small, with_actions):
    demos, discovery, _, _ = small
    truth = discovery.predict(np.concatenate([e.O for e in demos]), [e.T for e in demos])
    for demo, labels in zip(demos, truth):
        parse = with_actions.object_parse(demo.H, labels)
        if not any(with_actions.classes_[c].kind == "manipulation" for c in set(labels.tolist()) - {-1}):
            assert parse is None
            continue
        assert parse.shape == labels.shape and np.mean(parse == labels) > 0.95
        decoded = with_actions.decode(demo.H)
        assert [s.class_id for s in decoded] == [c for c, *_ in runs(labels) if c != -1]
        voted = np.concatenate([np.full(s.end - s.start, s.class_id) for s in decoded])
        assert np.mean(voted == labels[decoded[0].start:decoded[-1].end]) > 0.95


def test_pose_classes_refit_every_class_and_leave_the_recognition_classes_alone(small, posed):
    _, discovery, plain, _ = small
    assert plain.pose_classes_ == {}
    expected = sorted(c.primitive_id for c in discovery.classes_)
    assert sorted(posed.pose_classes_) == expected
    for cid, pose in posed.pose_classes_.items():
        same = posed.classes_[cid]
        assert pose.kind == same.kind and pose.phmm.n_states == same.phmm.n_states
        np.testing.assert_array_equal(pose.centre, same.centre)
        assert pose.phmm.mean_model == "tps" and same.phmm.mean_model == "linear"
    for cid, model in plain.classes_.items():  # the classes recognition and synthesis read are the same fit
        np.testing.assert_array_equal(posed.classes_[cid].phmm.mean_bar_, model.phmm.mean_bar_)
        np.testing.assert_array_equal(posed.classes_[cid].phmm.W_, model.phmm.W_)
    with pytest.raises(InvalidInputError, match="pose_mean_model must be None, 'linear' or 'tps'"):
        ActionModels(pose_mean_model="cubic")._check_params()


def test_pose_classes_survive_a_round_trip_and_older_directories_load_without_them(posed, tmp_path):
    path = tmp_path / "models"
    posed.save(path)
    again = ActionModels.load(path)
    assert sorted(again.pose_classes_) == sorted(posed.pose_classes_)
    for cid, pose in posed.pose_classes_.items():
        np.testing.assert_array_equal(again.pose_classes_[cid].phmm.V_, pose.phmm.V_)
    first = sorted(posed.pose_classes_)[0]
    other = next(c for c, model in posed.classes_.items() if model.kind == "manipulation")  # another kind
    edit_manifest(path, lambda m: m["pose_classes"][0].update(id=other, file=f"pose_{other}.npz"))
    shutil.copy(path / f"pose_{first}.npz", path / f"pose_{other}.npz")
    with pytest.raises(DataFileError, match=r"pose_classes\[\d+\] must refit a class of the same kind and states"):
        ActionModels.load(path)
    edit_manifest(path, lambda m: (m.update(format_version=3), m.pop("pose_classes")))
    for cid in posed.pose_classes_:
        (path / f"pose_{cid}.npz").unlink()
    assert ActionModels.load(path).pose_classes_ == {}


def test_the_tracker_poses_approach_and_remove_with_the_pose_classes_and_warns_without_them(small, posed):
    from hoap_actions.errors import MissingModelPartWarning
    from hoap_actions.tracking.tracking_models import TrackingModels

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tracked = TrackingModels.from_action_models(posed)
    for cid, model in posed.classes_.items():
        assert tracked.classes[cid] is posed.pose_classes_.get(cid, model)
    with pytest.warns(MissingModelPartWarning, match="no pose classes"):
        plain = TrackingModels.from_action_models(small[2])
    assert all(plain.classes[cid] is model for cid, model in small[2].classes_.items())


def test_learn_checks_its_hyper_parameters_before_reading_any_recording(tmp_path):
    from hoap_actions.primitives.pipelines.learn import learn

    with pytest.raises(InvalidInputError, match="pose_mean_model must be None, 'linear' or 'tps'"):
        learn([tmp_path / "not-recorded-yet.h5"], pose_mean_model="cubic")


def test_the_approach_ends_are_where_each_approach_left_the_hand_by_its_object(small, with_actions, tmp_path):
    """Read back from discovery's segmentations (another walk than the fit's, over demonstrations, not classes):
    each approach piece's last frame gives the hand marker's x and y less the object's, and its height."""
    demos, discovery, plain, _ = small
    kinds = {c.primitive_id: c.kind for c in discovery.classes_}
    expected = []
    for demo, segmentation in enumerate(discovery.segmentations_):
        for pid, _, end, *_ in segmentation:
            if kinds[pid] == "approach":
                hand, block = demos[demo].H[end - 1, discovery.hand_marker], demos[demo].O[end - 1, :3]
                expected.append([hand[0] - block[0], hand[1] - block[1], hand[2]])
    ends = with_actions.approach_ends_
    assert ends.shape == (len(expected), 3) and len(expected) > 0
    np.testing.assert_allclose(np.array(sorted(map(tuple, ends))), np.array(sorted(map(tuple, expected))))
    assert plain.approach_ends_ is None  # learned without object poses
    path = tmp_path / "models"
    with_actions.save(path)
    np.testing.assert_array_equal(ActionModels.load(path).approach_ends_, ends)
    for wrong, message in (([[0.0, float("nan"), 0.1]], "entry approach_ends must be"),
                           ([[0.0, 0.1]], "entry approach_ends must be"), ([], "non-empty list")):
        edit_manifest(path, lambda m, wrong=wrong: m.update(approach_ends=wrong))
        with pytest.raises(DataFileError, match=message):
            ActionModels.load(path)
    edit_manifest(path, lambda m: (m.update(format_version=4), m.pop("approach_ends")))
    assert ActionModels.load(path).approach_ends_ is None
