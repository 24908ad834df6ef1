"""The default selector (story) on bows and two-handed cuts built with free timing
(:mod:`snapcore.motion.synth_actions`), their key moments marked by the written
annotation rules (rule 1, bow: the head within 30 % of its lowest drop; rule 9, cut:
from the top of the raise to the hands' speed peak). A pick hits when it lies in an
interval widened by 0.1 s, as in ``snapshot keymoments``."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from snapcore.motion.synth_actions import bow_interval, bow_scene, slash_intervals, slash_scene
from snapcore.select.pose_methods import select_pose
from snapcore.select.stance import trunk_departure
from snapcore.select.story import DEFAULT_STORY

WIDEN_S = 0.1


def _hits(frames, intervals, fps) -> list[bool]:
    w = WIDEN_S * fps
    return [any(a - w <= f <= b + w for a, b in intervals) for f in frames]


def _picks(scene, params=DEFAULT_STORY) -> list[int]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return select_pose(scene, story=params).indices


def _shallow_bow(hands: str, fps: float, seed: int):
    """A 30-degree bow (the head drops about 6 cm) over 80 % of a 3 s clip, a small
    arm sway throughout."""
    return bow_scene(
        seconds=3.0,
        start_s=0.15,
        down_s=0.8,
        hold_s=0.8,
        up_s=0.8,
        depth_deg=30.0,
        hands=hands,
        sway_deg=4.0,
        fps=fps,
        seed=seed,
    )


# --------------------------------------------------------------------------- the rules


def test_bow_rule_marks_the_held_bow():
    """Rule 1 on a bow held from 1.0 s to 1.8 s (down 0.7 s, up 0.7 s): the interval
    covers the hold and ends within the down and up ramps, and the head drops 5-12 cm
    (the shallow bows of the shared gestures)."""
    fps = 30.0
    scene = bow_scene(start_s=0.3, down_s=0.7, hold_s=0.8, up_s=0.7, depth_deg=30.0, fps=fps)
    a, b = bow_interval(scene)
    assert 0.3 * fps < a <= 1.0 * fps and 1.8 * fps <= b < 2.5 * fps
    c = scene.characters[0]
    head = c.positions[:, c.skeleton.index("Head"), 1]
    assert 0.05 <= head.max() - head.min() <= 0.12


def test_cut_rule_ends_at_the_hands_speed_peak():
    """Rule 9 on three cuts: one interval per cut, from the end of the raise (95 % of
    the rise, in the last 0.2 s of the 0.5 s minimum-jerk raise that reaches the top at
    ``c - top_s``) to the speed peak, half-way through the minimum-jerk cut."""
    fps, cut_s, top_s = 60.0, 0.3, 0.15
    cuts = (1.0, 3.5, 6.0)
    scene = slash_scene(cuts_s=cuts, seconds=8.0, cut_s=cut_s, top_s=top_s, fps=fps)
    iv = slash_intervals(scene)
    assert len(iv) == 3
    for (a, b), c in zip(iv, cuts):
        assert abs(b - (c + cut_s / 2) * fps) <= 2, (b, c)
        assert (c - top_s - 0.2) * fps <= a <= (c - top_s) * fps, (a, c)


# --------------------------------------------------------------------------- the trunk term


def test_trunk_departure_known_answer():
    """Upright: 0 bits; the head turned forward by 30 degrees about the pelvis moves by
    2 L sin 15 degrees and carries 1/2 (d / spread)^2 / ln 2 bits; the same lean with
    both knees bent (ankles 20 cm nearer the pelvis) carries fewer bits."""
    stature, spread, spine = 1.75, 0.03, 0.55
    neutral = np.array(
        [
            [0, 1.5, 0],
            [0, 0.95, 0],
            [0.25, 0.8, 0],
            [-0.25, 0.8, 0],
            [0.1, 0.08, 0],
            [-0.1, 0.08, 0],
        ],
        dtype=float,
    )
    up = neutral.copy()
    lean = neutral.copy()
    th = math.radians(30)
    lean[0] = lean[1] + spine * np.array([0.0, math.cos(th), math.sin(th)])
    crouch = lean.copy()
    crouch[1:] -= [0.0, 0.2, 0.0]
    crouch[0] -= [0.0, 0.2, 0.0]
    crouch[4:] += [0.0, 0.2, 0.0]  # ankles stay on the floor: 20 cm nearer the pelvis
    bits = trunk_departure(np.stack([up, lean, crouch]), neutral, stature=stature, spread=spread)
    d = 2 * spine * math.sin(th / 2) / stature
    assert bits[0] == pytest.approx(0.0, abs=1e-12)
    assert bits[1] == pytest.approx(0.5 * (d / spread) ** 2 / math.log(2), rel=1e-9)
    assert bits[2] < 0.1 * bits[1]


# --------------------------------------------------------------------------- bows


@pytest.mark.parametrize("hands", ["sides", "hang", "clasped"])
@pytest.mark.parametrize("fps", [30.0, 120.0])
@pytest.mark.parametrize("seed", [0, 1])
def test_a_shallow_bow_filling_80_percent_of_the_clip(hands, fps, seed):
    """A shallow bow over 80 % of the clip, whatever the hands do: the top pick is on
    the bow (rule 1), not the rare rest at either end."""
    scene = _shallow_bow(hands, fps, seed)
    iv = [bow_interval(scene)]
    f = _picks(scene)[0]
    assert _hits([f], iv, fps)[0], (f, iv, scene.n_frames)


def test_the_shallow_bow_is_missed_without_the_trunk_term():
    """The failure the trunk term repairs: with it switched off, the shallow bow with
    the hands clasped in front (the arms depart from the stance more than the bow does)
    is missed at both frame rates (so the test above tests that term)."""
    for fps in (30.0, 120.0):
        scene = _shallow_bow("clasped", fps, 0)
        f = _picks(scene, DEFAULT_STORY.with_(trunk=False))[0]
        assert not _hits([f], [bow_interval(scene)], fps)[0], fps


@pytest.mark.parametrize("start_s", [0.1, 5.4])
def test_a_bow_early_or_late_in_a_long_rest(start_s):
    """A short, deep bow (45 degrees, 1.2 s) at the start or the end of a 7 s clip of
    rest: the pick follows the bow, wherever it is."""
    fps = 30.0
    scene = bow_scene(
        seconds=7.0, start_s=start_s, down_s=0.5, hold_s=0.2, up_s=0.5, depth_deg=45.0, fps=fps
    )
    iv = [bow_interval(scene)]
    f = _picks(scene)[0]
    assert _hits([f], iv, fps)[0], (f, iv)


# --------------------------------------------------------------------------- cuts


@pytest.mark.parametrize("cut_s", [0.15, 0.3])
@pytest.mark.parametrize("step_m", [0.0, 0.4])
@pytest.mark.parametrize("fps", [30.0, 60.0])
def test_three_cuts_with_long_follow_throughs(cut_s, step_m, fps):
    """Three cuts, each followed by a 1.8 s follow-through (trunk leaning on, knees
    giving, with or without a step in and the rear foot following): the top pick and
    each of the top three lie between the top of a raise and the hands' speed peak,
    not in the longer settling after it."""
    scene = slash_scene(
        cuts_s=(0.9, 3.6, 6.3),
        seconds=8.6,
        cut_s=cut_s,
        follow_s=1.8,
        step_m=step_m,
        lean_deg=25.0,
        lunge_m=0.08,
        fps=fps,
    )
    iv = slash_intervals(scene)
    picks = _picks(scene)
    assert len(picks) == 3 and all(_hits(picks, iv, fps)), (picks, iv)


def test_a_cut_late_in_the_clip_with_a_follow_through_to_the_end():
    """One cut near the end, whose follow-through lasts to the clip's last frame: the
    pick is on the cut."""
    fps = 30.0
    scene = slash_scene(cuts_s=(3.0,), seconds=5.0, follow_s=3.0, step_m=0.3, fps=fps)
    iv = slash_intervals(scene)
    f = _picks(scene)[0]
    assert _hits([f], iv, fps)[0], (f, iv)


# --------------------------------------------------------------------------- strikes


def test_strike_surprisal_known_answer():
    """A wrist that strikes twice (speed peaks of 5 statures/s) in 100 frames: each
    strike carries -log2(2/100) bits at its peak (no support); with support they go to
    the frames before the peak only, and a slow hand (1 stature/s) is no strike."""
    from snapcore.select.strikes import strike_surprisal

    fps, stature, n = 100.0, 1.0, 100
    from scipy.special import erf

    t = np.arange(n) / fps
    sig = 0.03
    # the left wrist moves forward with speed 5 exp(-(t - c)^2 / 2 sig^2) around c = 0.3,
    # 0.7 s: its position is the integral of that
    x = np.zeros((n, 6, 3))
    for c in (0.3, 0.7):
        x[:, 2, 2] += 5.0 * sig * math.sqrt(math.pi / 2) * erf((t - c) / (sig * math.sqrt(2)))
    bits = strike_surprisal(x, fps=fps, stature=stature, support_s=0.0)
    peaks = np.flatnonzero(bits)
    assert peaks.tolist() == [30, 70]
    assert bits[peaks] == pytest.approx(-math.log2(2 / n))
    spread = strike_surprisal(x, fps=fps, stature=stature, support_s=0.05)
    assert spread[25:31].min() > 0 and np.all(spread[31:40] == 0)
    x[:, 2, 2] *= 0.2
    assert not strike_surprisal(x, fps=fps, stature=stature).any()


def test_strikes_credit_the_approach_to_the_cut():
    """On three cuts with long follow-throughs, the strike term credits the approach --
    it is largest at or before the hands' speed peak (the raise is fast too) and
    positive through the rule-9 interval -- and gives the follow-through (0.2-1.5 s
    after the speed peak) nothing; a bow has no strike."""
    from snapcore.select.story import story_information

    fps = 60.0
    scene = slash_scene(cuts_s=(0.9, 3.6, 6.3), seconds=8.6, follow_s=1.8, step_m=0.3, fps=fps)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        strikes = story_information(scene).strike_bits
    for a, b in slash_intervals(scene):
        f = a - int(0.3 * fps) + int(np.argmax(strikes[a - int(0.3 * fps) : b + int(fps)]))
        assert f <= b and strikes[a : b + 1].min() > 0, (f, a, b)
        assert np.all(strikes[b + int(0.2 * fps) : b + int(1.5 * fps)] == 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert not story_information(_shallow_bow("sides", fps, 0)).strike_bits.any()
