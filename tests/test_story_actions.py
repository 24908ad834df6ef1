"""The default selector (story) on generated actions whose place in the clip is known:
a gesture filling most of the clip with rest at both ends, the same gesture early in a
clip of rest, and a kick repeated three times; several seeds and frame rates. The top
pick must lie on the action (the frames where the gesture or kick is within 20 % of its
peak, widened by 0.1 s as in ``snapshot keymoments``).

The clips are built here from the procedural rig (:mod:`snapcore.motion.synth_rig`) on
the person standing at rest of :func:`snapcore.motion.synth_actions.standing` (breathing
and sway, so that no frame is exactly still)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from snapcore.motion.synth_actions import pose_scene as _scene
from snapcore.motion.synth_actions import standing as _standing
from snapcore.motion.synth_rig import ANKLE_HEIGHT, ROOT_HEIGHT_M, SIDES, arm_fk, pchip, rx, zxy
from snapcore.select.pose_methods import select_pose

WIDEN_S = 0.1


def _gesture(fps: float, seed: int, *, seconds: float, start_s: float, end_s: float):
    """Raise the right hand above the head and wave it, from ``start_s`` to ``end_s``
    (rise and fall take 0.3 s each); at rest before and after.

    Returns the scene and the action's frames (abduction >= 80 % of its peak)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(seconds * fps)) + 1) / fps
    pose = _standing(t, rng)
    peak = 160.0 + rng.uniform(-10, 10)
    up = pchip(
        t,
        [0.0, start_s, start_s + 0.3, end_s - 0.3, end_s, seconds],
        [0.0, 0.0, 1.0, 1.0, 0.0, 0.0],
    )
    wave = 12.0 * np.sin(2 * np.pi * 2.0 * (t - start_s)) * up
    arm_fk(pose, "Right", 8.0 + (peak - 8.0) * up + wave, 10.0 * up, 14.0 + 30.0 * up)
    action = np.flatnonzero(up >= 0.8)
    return _scene(pose, fps, "gesture"), action


def _kicks(fps: float, seed: int, *, seconds: float = 6.0, times=(1.2, 3.0, 4.8)):
    """Three right front kicks (hip flexion peaks at ``times``) from a guard stance,
    the left foot planted. Returns the scene and the frames of the kicks (hip flexion
    >= 80 % of that kick's peak)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(seconds * fps)) + 1) / fps
    pose = _standing(t, rng)
    hip = np.zeros_like(t)
    knee = np.zeros_like(t)
    for tk in times:
        h = 80.0 + rng.uniform(-8, 8)
        keys = [tk - 0.6, tk - 0.25, tk, tk + 0.25, tk + 0.6]
        inside = (t >= keys[0]) & (t <= keys[-1])
        hip[inside] += pchip(t[inside], keys, [0.0, 45.0, h, 45.0, 0.0])
        knee[inside] += pchip(t[inside], keys, [0.0, 100.0, 5.0, 90.0, 0.0])
    pose.local["RightUpLeg"] = rx(-hip)
    pose.local["RightLeg"] = rx(knee)
    for side in SIDES:
        arm_fk(pose, side, 20.0, 40.0, 110.0)
    peaks = [
        np.flatnonzero((np.abs(t - tk) < 0.6) & (hip >= 0.8 * hip[np.abs(t - tk) < 0.6].max()))
        for tk in times
    ]
    return _scene(pose, fps, "kicks"), np.concatenate(peaks)


def _bow(
    fps: float, seed: int, *, seconds: float, start_s: float, end_s: float, depth_deg: float = 30.0
):
    """A bow: the trunk flexes by ``depth_deg`` (+-5, spine, chest and neck), held 0.4 s
    around the middle of ``start_s``..``end_s``. Returns the scene and the frames within
    30 % of the deepest flexion."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(seconds * fps)) + 1) / fps
    pose = _standing(t, rng)
    mid = 0.5 * (start_s + end_s)
    flex = pchip(
        t, [0.0, start_s, mid - 0.2, mid + 0.2, end_s, seconds], [0.0, 0.0, 1.0, 1.0, 0.0, 0.0]
    ) * (depth_deg + rng.uniform(-5, 5))
    pose.local["Spine"] = pose.local["Spine"] @ zxy(0.0, 0.6 * flex, 0.0)
    pose.local["Spine1"] = zxy(0.0, 0.4 * flex, 0.0)
    pose.local["Neck"] = zxy(0.0, 0.3 * flex, 0.0)
    return _scene(pose, fps, "bow"), np.flatnonzero(flex >= 0.7 * flex.max())


def _on_action(frame: int, action: np.ndarray, fps: float) -> bool:
    return bool(np.min(np.abs(action - frame)) <= WIDEN_S * fps)


def _top(scene) -> int:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return select_pose(scene).index


@pytest.mark.parametrize("fps", [30.0, 60.0, 120.0])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gesture_filling_most_of_the_clip(fps, seed):
    """Gesture over 80 % of a 4 s clip, rest at both ends: the rest pose is the rare one
    in this clip, the action must still win."""
    scene, action = _gesture(fps, seed, seconds=4.0, start_s=0.4, end_s=3.6)
    assert action.size > 0.6 * scene.n_frames
    f = _top(scene)
    assert _on_action(f, action, fps), (f, action.min(), action.max(), scene.n_frames)


@pytest.mark.parametrize("fps", [30.0, 60.0, 120.0])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_gesture_in_the_first_15_percent(fps, seed):
    """The same gesture early in a 7 s clip (0.1 s to 1.05 s), rest for the remaining
    85 %: no preference for the middle of the clip may pull the pick away."""
    scene, action = _gesture(fps, seed, seconds=7.0, start_s=0.1, end_s=1.05)
    assert action.max() < 0.15 * scene.n_frames
    f = _top(scene)
    assert _on_action(f, action, fps), (f, action.min(), action.max(), scene.n_frames)


@pytest.mark.parametrize("fps", [30.0, 60.0, 120.0])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_kick_repeated_three_times(fps, seed):
    """Three kicks: the pick is on one of them (any counts)."""
    scene, action = _kicks(fps, seed)
    f = _top(scene)
    assert _on_action(f, action, fps), (f, action.min(), action.max(), scene.n_frames)


@pytest.mark.parametrize("fps", [30.0, 120.0])
@pytest.mark.parametrize("seed", [0, 1])
def test_a_moderate_bow_filling_the_clip(fps, seed):
    """A 30-degree bow over 80 % of a 3 s clip: the head barely drops (4 % of the
    stature) but leans forward; the pick is at the deepest bow, not the rare rest."""
    scene, action = _bow(fps, seed, seconds=3.0, start_s=0.3, end_s=2.7)
    f = _top(scene)
    assert _on_action(f, action, fps), (f, action.min(), action.max(), scene.n_frames)


def test_the_rest_pose_wins_without_the_stance_term():
    """The failure this selector repairs: with the departure from the neutral stance
    switched off, the gesture clip's top pick is the rare rest pose (so the tests above
    test that term)."""
    from snapcore.select.story import DEFAULT_STORY

    scene, action = _gesture(30.0, 0, seconds=4.0, start_s=0.4, end_s=3.6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = select_pose(scene, story=DEFAULT_STORY.with_(stance=False)).index
    assert not _on_action(f, action, 30.0)


def test_neutral_stance_of_the_synthetic_rig():
    """The neutral stance comes from the skeleton: on the procedural rig (its bone
    lengths are module constants) the pelvis stands at ROOT_HEIGHT_M, the head 0.55 m
    above it (spine, neck and head bones), the wrists hang the arm's length (0.54 m)
    below the shoulder joints (0.41 m above the pelvis), the ankles at ANKLE_HEIGHT;
    whatever the clip does (a kick clip gives the same stance as standing idle)."""
    from snapcore.motion import synth
    from snapcore.motion.synth_rig import FOREARM, UPPER_ARM
    from snapcore.select.stance import neutral_stance

    for name in ("idle", "kick"):
        scene = synth.synth_scene(name, fps=30)
        n = neutral_stance(scene.characters[0], ground=scene.ground)
        head, pelvis, wrist_l, wrist_r, ankle_l, ankle_r = n
        assert pelvis[1] == pytest.approx(ROOT_HEIGHT_M, abs=0.01), name
        assert head[1] - pelvis[1] == pytest.approx(0.10 + 0.14 + 0.21 + 0.10, abs=0.01)
        shoulder = pelvis[1] + 0.10 + 0.14 + 0.17
        assert wrist_l[1] == pytest.approx(shoulder - UPPER_ARM - FOREARM, abs=0.02), name
        assert wrist_r[1] == pytest.approx(wrist_l[1])
        assert ankle_l[1] == pytest.approx(ANKLE_HEIGHT, abs=0.01), name
        assert wrist_l[0] > 0 > wrist_r[0] and ankle_l[0] > 0 > ankle_r[0]


def test_rest_departs_little_and_a_raised_hand_much():
    """Standing at rest is within a few bits of the neutral stance; the raised hand of
    the gesture clip departs by tens of bits."""
    from snapcore.motion.anatomy import stature_of
    from snapcore.select.stance import descriptor_of, neutral_stance, pose_descriptor
    from snapcore.select.story import stance_departure

    scene, action = _gesture(30.0, 0, seconds=4.0, start_s=0.4, end_s=3.6)
    c = scene.characters[0]
    nd = descriptor_of(neutral_stance(c, ground=0.0)[None], ground=0.0, stature=stature_of(c))[0]
    bits = stance_departure(pose_descriptor(c, ground=0.0, fps=30.0), nd, spread=0.1)
    assert bits[:5].max() < 3.0 and bits[-5:].max() < 3.0
    assert bits[action].min() > 30.0
