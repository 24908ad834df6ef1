"""The story selector (snapcore.select.story) and the selectors behind select_pose: known
answers of each ingredient, invariances, the static clip, contact quality on the
shared walks/runs, synthetic actions with documented times, and the annotated key
moments of ../shared/keymoments."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from snapcore import load_scene, select_pose
from snapcore.motion import synth
from snapcore.motion.scene import Scene
from snapcore.select.pose_baselines import interpolation_error_table, middle_frames, random_frames
from snapcore.select.pose_methods import POSE_METHODS
from snapcore.select.story import (
    DEFAULT_STORY,
    StoryParams,
    debounced_contacts,
    enforce_min_durations,
    event_surprisal,
    hysteresis,
    limb_groups,
    pose_surprisal,
    story_information,
)


def _quiet(fn, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*a, **kw)


# --------------------------------------------------------------------------- ingredients


def test_hysteresis_keeps_state_inside_the_band():
    """On at <= 1, off above 2, unchanged in between; starts off."""
    s = np.array([1.5, 0.5, 1.5, 1.9, 2.5, 1.5, 0.9, 3.0])
    assert hysteresis(s, 1.0, 2.0).tolist() == [False, True, True, True, False, False, True, False]
    two = np.stack([s, s[::-1]], axis=1)  # columns switch independently
    np.testing.assert_array_equal(hysteresis(two, 1.0, 2.0)[:, 0], hysteresis(s, 1.0, 2.0))


def test_min_durations_close_gaps_then_drop_short_contacts():
    """A 1-frame gap inside a contact closes; a 2-frame contact goes; an edge gap stays."""
    b = np.array([0, 1, 1, 1, 0, 1, 1, 1, 0, 0, 0, 1, 1, 0, 0, 0], dtype=bool)
    out = enforce_min_durations(b, min_on=3, min_off=2)
    assert out.tolist() == [False] + [True] * 7 + [False] * 8


def test_min_durations_rows_are_independent():
    """Rows of a (L, F) state are debounced each on its own: a gap at the end of one
    row and one at the start of the next touch clip edges (kept, not one interior gap),
    and a contact running into the next row's start is two contacts."""
    rows = np.array(
        [
            [1, 1, 1, 1, 0, 0, 0, 1, 1, 1, 1, 0],  # a 3-frame gap stays; the edge gap too
            [0, 1, 1, 1, 0, 0, 1, 1, 1, 1, 1, 1],  # the edge gap stays; a 2-frame gap closes
            [1, 1, 0, 0, 0, 1, 1, 1, 0, 0, 0, 0],  # the 2-frame contact at the start goes
        ],
        dtype=bool,
    )
    out = enforce_min_durations(rows, min_on=3, min_off=3)
    assert out.astype(int).tolist() == [
        [1, 1, 1, 1, 0, 0, 0, 1, 1, 1, 1, 0],
        [0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1],
        [0, 0, 0, 0, 0, 1, 1, 1, 0, 0, 0, 0],
    ]
    for row, want in zip(rows, out):  # the same as one row at a time
        np.testing.assert_array_equal(enforce_min_durations(row, 3, 3), want)


def test_event_surprisal_known_answer():
    """One release in F frames carries log2(F) bits, credited from the release on (the
    free phase), nothing before; an onset credits the frames before it."""
    n_f = 64
    st = np.zeros((1, n_f), dtype=bool)
    st[0, :20] = True  # released at frame 20 (first free frame)
    bits = event_surprisal(st, fps=10.0, support_s=0.0)
    assert bits[20] == pytest.approx(np.log2(n_f)) and bits.sum() == pytest.approx(np.log2(n_f))
    spread = event_surprisal(st, fps=10.0, support_s=0.2)
    assert spread[20] == pytest.approx(np.log2(n_f))
    assert spread[:20].max() == 0 and spread[21] > 0  # after, not before
    on = np.zeros((1, n_f), dtype=bool)
    on[0, 40:] = True  # onset at 40
    sp = event_surprisal(on, fps=10.0, support_s=0.2)
    assert sp[41:].max() == 0 and sp[39] > 0 and sp[40] == pytest.approx(np.log2(n_f))


def test_rare_events_carry_more_bits():
    """An event kind seen once carries more than each of one seen five times."""
    n_f = 200
    st = np.zeros((2, n_f), dtype=bool)
    st[0, 10:150] = True  # limb 0: one release at 150
    for s in range(0, 200, 40):
        st[1, s + 5 : s + 25] = True  # limb 1: five releases
    bits = event_surprisal(st, fps=10.0, support_s=0.0)
    assert bits[150] == pytest.approx(np.log2(200))
    assert bits[25] == pytest.approx(np.log2(200 / 5))


def test_pose_surprisal_peaks_at_the_outlier_and_is_zero_when_static():
    """The one frame far from the others is the most surprising; a constant descriptor
    gives 0 bits everywhere (no NaN)."""
    rng = np.random.default_rng(0)
    x = rng.normal(scale=0.05, size=(300, 6))
    x[123] += 0.6
    assert int(np.argmax(pose_surprisal(x))) == 123
    flat = pose_surprisal(np.ones((50, 6)))
    assert np.all(flat == 0)


def test_parameters_are_checked():
    """Negative, inverted hysteresis, unknown model, both weights 0: ValueError."""
    with pytest.raises(ValueError, match="support_s"):
        StoryParams(support_s=-1)
    with pytest.raises(ValueError, match="hysteresis"):
        StoryParams(release_height=0.05)
    with pytest.raises(ValueError, match="event_model"):
        StoryParams(event_model="bogus")
    with pytest.raises(ValueError, match="w_pose"):
        StoryParams(w_pose=0, w_event=0)


def test_limb_groups_one_contactor_per_leg():
    """The synthetic humanoid's knee, foot and toe joints make one leg contactor; the
    thigh (never lower than the knee) and the other leg's joints are not in it."""
    scene = synth.synth_scene("walk", fps=30)
    names, joints = limb_groups(scene.characters[0])
    c = scene.characters[0]
    left = joints[names.index("legL")]
    assert {c.joint_names[j] for j in left} >= {"LeftLeg", "LeftFoot", "LeftToeBase"}
    assert "LeftUpLeg" not in {c.joint_names[j] for j in left}
    assert not {c.joint_names[j] for j in joints[names.index("legR")]} & {"LeftFoot"}


# --------------------------------------------------------------------------- the selector


@pytest.mark.parametrize("name", ["kick", "jump", "punch"])
def test_story_invariant_under_yaw_translation_and_unit(name):
    """The chosen frame does not change when the scene is turned, moved or rescaled."""
    scene = synth.synth_scene(name, fps=60)
    base = _quiet(select_pose, scene, method="story").index
    for kw in ({"yaw_deg": 73.0}, {"offset": (3.0, 0.4, -2.0)}, {"scale": 100.0 / 2.54}):
        assert _quiet(select_pose, scene.transformed(**kw), method="story").index == base, kw


def test_story_invariant_on_real_clip(motions_dir):
    """Same on a real clip (CMU 10_01): yaw, translation, metres to centimetres."""
    scene = _quiet(load_scene, motions_dir / "soccer" / "10_01.bvh")
    base = _quiet(select_pose, scene).indices
    for kw in ({"yaw_deg": -120.0}, {"offset": (-5.0, 0.0, 7.0)}, {"scale": 100.0}):
        assert _quiet(select_pose, scene.transformed(**kw)).indices == base, kw


def test_static_clip_gives_a_defined_frame_and_warns():
    """Every frame equal: frame 0 with a warning, finite scores, no exception."""
    scene = synth.synth_scene("idle", fps=30)
    c = scene.characters[0]
    c.positions = np.repeat(c.positions[:1], c.n_frames, axis=0)
    still = Scene([c], fps=scene.fps, ground=scene.ground)
    with pytest.warns(UserWarning, match="static clip"):
        sel = select_pose(still, method="story")
    assert sel.index == 0 and sel.method == "story"
    assert np.all(np.isfinite(sel.scores.total)) and sel.entropy is None


@pytest.mark.parametrize("fps", [30, 120])
def test_story_finds_synthetic_actions(fps):
    """Documented synth times: the top pick lies in the jump's flight, within the kick's
    backswing-to-impact (knee most bent 0.25 s before impact in the synth keys), and
    within 0.15 s of the punch's full extension."""
    jump = _quiet(select_pose, synth.synth_scene("jump", fps=fps)).index / fps
    assert synth.JUMP_TAKEOFF_S <= jump <= synth.JUMP_LANDING_S
    kick = _quiet(select_pose, synth.synth_scene("kick", fps=fps)).index / fps
    assert synth.KICK_IMPACT_S - 0.3 <= kick <= synth.KICK_IMPACT_S + 0.1
    punch = _quiet(select_pose, synth.synth_scene("punch", fps=fps)).index / fps
    assert abs(punch - synth.PUNCH_IMPACT_S) <= 0.15


def test_ablation_switches_change_the_ingredients():
    """Each switch removes its ingredient: w_event=0 leaves zero event and strike terms,
    w_pose=0 zero pose terms, stance/trunk/novelty/strikes off their
    own term; the terms add up to the total."""
    scene = synth.synth_scene("jump", fps=60)
    full = _quiet(story_information, scene)
    assert set(full.terms) == {"stance", "trunk", "novelty", "events", "strikes"}
    assert all(full.terms[k].max() > 0 for k in full.terms)
    np.testing.assert_allclose(sum(full.terms.values()), full.total, rtol=1e-12)
    info = _quiet(story_information, scene, DEFAULT_STORY.with_(w_event=0.0))
    assert np.all(info.terms["events"] == 0) and info.terms["stance"].max() > 0
    assert np.all(info.terms["strikes"] == 0)
    info = _quiet(story_information, scene, DEFAULT_STORY.with_(w_pose=0.0))
    assert np.all(info.terms["stance"] == 0) and np.all(info.terms["novelty"] == 0)
    assert np.all(info.terms["trunk"] == 0)
    assert info.terms["events"].max() > 0
    info = _quiet(story_information, scene, DEFAULT_STORY.with_(strikes=False))
    assert np.all(info.terms["strikes"] == 0) and info.terms["events"].max() > 0
    info = _quiet(story_information, scene, DEFAULT_STORY.with_(trunk=False))
    assert np.all(info.trunk_bits == 0) and np.all(info.terms["trunk"] == 0)
    assert info.stance_bits.max() > 0
    info = _quiet(story_information, scene, DEFAULT_STORY.with_(stance=False))
    assert np.all(info.stance_bits == 0) and info.novelty_bits.max() > 0
    info = _quiet(story_information, scene, DEFAULT_STORY.with_(novelty=False))
    assert np.all(info.novelty_bits == 0) and info.stance_bits.max() > 0
    info = _quiet(story_information, scene, DEFAULT_STORY.with_(combine="normalised"))
    assert set(info.terms) == {"pose", "events"} and info.terms["pose"].max() <= 1


# --------------------------------------------------------------------------- contact quality


def _steps_from_heel_minima(c, fps, foot):
    """Independent step count (as tests/test_contacts.py): prominent (>= 2 cm) minima
    of the heel height, merged unless the foot's lowest point rose >= 3 cm between."""
    from scipy.signal import find_peaks

    heel = foot[0]
    h = c.positions[:, heel, 1]
    low = c.positions[:, foot, 1].min(axis=1)
    padded = np.r_[h.max(), h, h.max()]
    minima, _ = find_peaks(-padded, prominence=0.02, distance=max(1, int(0.2 * fps)))
    steps = []
    for k in minima - 1:
        if steps and low[steps[-1] : k + 1].max() - max(low[steps[-1]], low[k]) < 0.03:
            continue
        steps.append(k)
    return steps


def test_debounced_contacts_one_per_footstep(motions_dir):
    """walk_run/: per leg, debounced contacts = steps from heel minima (+-1), and no
    contact shorter than min_contact_s nor interior gap shorter than min_gap_s."""
    from snapcore.motion.anatomy import joint_roles

    files = sorted((motions_dir / "walk_run").glob("*.bvh"))
    assert len(files) == 4
    p = DEFAULT_STORY
    for path in files:
        scene = _quiet(load_scene, path)
        c = scene.characters[0]
        lc = debounced_contacts(c, ground=scene.ground, fps=scene.fps)
        roles = joint_roles(c.joint_names, tuple(c.parents.tolist()))
        for leg in ("legL", "legR"):
            li = lc.names.index(leg)
            foot = [int(j) for j in lc.joints[li] if roles[j] in ("foot", "toe")]
            contacts = lc.intervals(li)
            steps = _steps_from_heel_minima(c, scene.fps, foot)
            assert len(contacts) >= 2, (path.name, leg)
            assert abs(len(contacts) - len(steps)) <= 1, (path.name, leg, contacts, steps)
            lengths = np.array([e - s + 1 for s, e in contacts])
            assert lengths.min() >= round(p.min_contact_s * scene.fps), (path.name, leg)
            gaps = np.array([s2 - e1 - 1 for (_, e1), (s2, _) in zip(contacts, contacts[1:])])
            assert gaps.size == 0 or gaps.min() >= round(p.min_gap_s * scene.fps), (path.name, leg)


# --------------------------------------------------------------------------- baselines


def test_salient_error_table_matches_direct_sums():
    """Interpolation errors from prefix sums equal the direct sum over the segment."""
    rng = np.random.default_rng(1)
    x = rng.normal(size=(30, 4))
    keys = np.array([0, 3, 7, 20, 29])
    err = interpolation_error_table(x, keys)
    for a in range(5):
        for b in range(a + 1, 5):
            s, e = keys[a], keys[b]
            t = (np.arange(s, e + 1) - s) / (e - s)
            ref = np.square(x[s : e + 1] - ((1 - t)[:, None] * x[s] + t[:, None] * x[e])).sum()
            assert err[a, b] == pytest.approx(ref, rel=1e-9, abs=1e-9)


def test_salient_finds_the_corner_of_a_polyline():
    """A joint that goes out and back linearly: the best single key is the turn."""
    scene = synth.synth_scene("idle", fps=30)
    c = scene.characters[0]
    n = c.n_frames
    tri = np.minimum(np.arange(n), 40) - np.maximum(np.arange(n) - 40, 0)  # corner at 40
    c.positions = np.repeat(c.positions[:1], n, axis=0)
    c.positions[:, :, 0] += 0.01 * tri[:, None]
    sel = select_pose(Scene([c], fps=30.0), method="salient", k=1)
    assert sel.index == 40


def test_middle_and_random_baselines():
    """middle: the middle frame first; random: reproducible by seed, distinct frames."""
    assert middle_frames(101, 3) == [50, 25, 75]
    a, b = (
        random_frames(500, 3, seed=7, min_separation=30),
        random_frames(500, 3, seed=7, min_separation=30),
    )
    assert a == b and len(set(a)) == 3
    assert min(abs(x - y) for i, x in enumerate(a) for y in a[i + 1 :]) >= 30
    assert random_frames(500, 3, seed=8) != a


def test_every_method_returns_a_selection():
    """Each named method returns frames in the clip with method recorded; an unknown
    one and paper options on another method are refused."""
    scene = synth.synth_scene("jump", fps=30)
    for m in POSE_METHODS:
        sel = _quiet(select_pose, scene, method=m, k=3)
        assert sel.method == m and 0 <= sel.index < scene.n_frames
        assert sel.indices[0] == sel.index and len(sel.indices) <= 3
    with pytest.raises(ValueError, match="method"):
        select_pose(scene, method="best")
    with pytest.raises(ValueError, match="paper"):
        select_pose(scene, method="story", w_local=2.0)


# --------------------------------------------------------------------------- key moments


def test_keymoments_acceptance(motions_dir):
    """../shared/keymoments: the story selector's top-1 hits >= 5 of 6 scenes, its top-3
    all 6, and no baseline's top-1 hits more scenes."""
    from snapcore.select.keymoments import read_keymoments, run_keymoments

    path = motions_dir.parent / "keymoments" / "keymoments.tsv"
    if not path.exists():
        pytest.skip(f"no annotations at {path}")
    doc = run_keymoments(read_keymoments(path), data=motions_dir, methods=POSE_METHODS)
    overall = {o["method"]: o for o in doc["overall"]}
    assert overall["story"]["n_scenes"] == 6
    assert overall["story"]["top1_hits"] >= 5
    assert overall["story"]["top3_hits"] == 6
    for m, o in overall.items():
        assert o["top1_hits"] <= overall["story"]["top1_hits"], m


@pytest.mark.parametrize("name,fps", [("push", 30), ("kick", 60), ("punch", 24)])
def test_story_shares_one_gather_without_changing_contacts_or_strikes(name, fps):
    """The story computes every character's contacts and strikes from one shared gather
    of its joints (heights and speeds once); each must equal its stand-alone function
    (24 fps: a Savitzky-Golay window wider than 3 frames, so the smoothing is not the
    identity there)."""
    from snapcore.motion.anatomy import stature_of
    from snapcore.select.stance import key_positions
    from snapcore.select.story import DEFAULT_STORY, debounced_contacts, story_information
    from snapcore.select.strikes import strike_surprisal

    scene = synth.synth_scene(name, fps=fps)
    p = DEFAULT_STORY.with_(event_support_s=0.0, support_s=0.0)
    info = _quiet(story_information, scene, p)
    strikes = np.zeros(scene.n_frames)
    for c, lc in zip(scene.characters, info.contacts):
        alone = debounced_contacts(c, ground=scene.ground, fps=float(scene.fps), params=p)
        np.testing.assert_array_equal(lc.state, alone.state)
        x = key_positions(c, fps=float(scene.fps), smooth_s=p.smooth_s)
        strikes += strike_surprisal(
            x, fps=float(scene.fps), stature=stature_of(c), threshold=p.strike_speed, support_s=0.0
        )
    if float(strikes.max() - strikes.min()) <= 1e-12:
        strikes[:] = 0.0
    np.testing.assert_allclose(info.strike_bits, strikes, rtol=0, atol=1e-9)
