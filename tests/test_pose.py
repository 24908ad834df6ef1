"""Pose entropy (METHOD §1): analytic cases, invariances, and the fast code against a
deliberately simple per-frame loop implementation of the whole method.

The reference (``reference_*`` below) is written from METHOD.md, not from the library:
it loops over frames, fits the smoothing polynomials with ``np.polyfit``, measures
turning angles with ``arctan2(|a x b|, a . b)`` and rotation changes with SciPy's
``Rotation.magnitude``, finds contacts with the plain scan "seed, then propagate"
frame by frame, and marks events from a dictionary. Only constants (tolerances, the
capsule radii of the body, the window length) are shared with the library.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from snapcore import load_scene
from snapcore.motion import synth
from snapcore.motion.scene import Character, Scene, Skeleton
from snapcore.select.contacts import DEFAULT_TOLERANCES, bone_radii
from snapcore.select.paper import (
    REST_SPEED,
    global_entropy,
    joint_curvature,
    limb_lengths,
    local_entropy,
    local_information,
    pose_entropy,
    rotation_change,
)
from snapcore.select.pose_methods import select_pose
from snapcore.select.pose_selection import top_peaks
from snapcore.select.signals import SAVGOL_POLYORDER, SMOOTH_S, minmax, smooth_positions

SALSA_PAIRS = [
    ("two_person/60_01_scaled.bvh", "two_person/61_01_scaled.bvh"),
    ("two_person/60_12_scaled.bvh", "two_person/61_12_scaled.bvh"),
]


def _load(paths, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the salsa unit is fitted, which warns
        return load_scene(paths, **kw)


def _quiet(fn, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*a, **kw)


# --------------------------------------------------------------------------- builders


def _chain_character(
    root_positions, root_rotations, *, child_offset=(0.0, 0.0, 0.5), fps=30.0, name="probe"
):
    """A two-joint skeleton (root + end site) driven by the given root path/rotations."""
    root_positions = np.asarray(root_positions, float)
    root_rotations = np.asarray(root_rotations, float)
    n = root_positions.shape[0]
    off = np.asarray(child_offset, float)
    sk = Skeleton(
        ("root", "root_End"), np.array([-1, 0]), np.array([[0, 0, 0], off]), np.array([False, True])
    )
    child = root_positions + root_rotations @ off
    pos = np.stack([root_positions, child], axis=1)
    rot = np.stack([root_rotations, root_rotations], axis=1)
    local = np.stack([root_rotations, np.broadcast_to(np.eye(3), (n, 3, 3))], axis=1)
    return Character(
        name=name,
        skeleton=sk,
        positions=pos,
        rotations=rot,
        local_rotations=local.copy(),
        fps=fps,
        scale=1.0,
    )


def _spin(n, rate_rad, axis=(0.0, 1.0, 0.0)):
    """Rotations about ``axis`` by ``rate_rad`` per frame, shape (n, 3, 3)."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return Rotation.from_rotvec(np.outer(np.arange(n) * rate_rad, axis)).as_matrix()


# --------------------------------------------------------------------------- analytic


@pytest.mark.parametrize("n_per_rev", [12, 40, 97])
@pytest.mark.parametrize("smooth_s", [0.0, SMOOTH_S])
def test_circle_curvature_is_sin_pi_over_n(n_per_rev, smooth_s):
    """A joint on a circle, N points per revolution: theta = 2 pi / N, kappa = sin(pi / N)."""
    fps = 60.0
    i = np.arange(3 * n_per_rev)
    phi = 2 * np.pi * i / n_per_rev
    x = np.stack([0.4 * np.cos(phi), 1.0 + 0.0 * phi, 0.4 * np.sin(phi)], axis=1)[:, None]
    kappa = joint_curvature(x, fps=fps, smooth_s=smooth_s, rest_speed=REST_SPEED)[:, 0]
    # Savitzky-Golay is a symmetric linear filter: in the interior it maps a uniformly
    # sampled circle to a smaller, still uniformly sampled circle; the ends are fitted.
    h = int(round(smooth_s * fps)) // 2 + 1
    inner = kappa[h + 1 : -h - 1]
    np.testing.assert_allclose(inner, math.sin(math.pi / n_per_rev), rtol=1e-9)
    assert kappa[0] == 0 and kappa[-1] == 0


def test_curvature_of_a_right_angle_is_sin_45_deg():
    """A 90-degree corner between two straight runs: kappa = sin(45 deg) at the corner only."""
    a = np.stack([np.arange(10.0) * 0.05, np.ones(10), np.zeros(10)], axis=1)
    b = np.stack([np.full(9, 0.45), np.ones(9), np.arange(1, 10) * 0.05], axis=1)
    x = np.concatenate([a, b])[:, None]
    kappa = joint_curvature(x, fps=30, smooth_s=0, rest_speed=REST_SPEED)[:, 0]
    assert kappa[9] == pytest.approx(math.sin(math.pi / 4), rel=1e-12)
    assert np.all(np.delete(kappa, 9) < 1e-12)


def test_resting_joint_has_zero_curvature():
    """Jitter below the rest speed does not count as turning (the noise floor)."""
    rng = np.random.default_rng(3)
    x = (np.array([0.0, 1.0, 0.0]) + rng.normal(scale=1e-5, size=(50, 3)))[:, None]
    kappa = joint_curvature(x, fps=120, smooth_s=0, rest_speed=REST_SPEED)
    assert np.all(kappa == 0)


def test_rotation_change_recovers_known_angles():
    """Rotations about a fixed axis by known per-frame steps give those steps back."""
    rng = np.random.default_rng(0)
    steps = rng.uniform(1e-6, 0.5, size=40)
    angles = np.r_[0.0, np.cumsum(steps)]
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    base = Rotation.from_euler("ZXY", [20, -35, 70], degrees=True).as_matrix()
    r = base @ Rotation.from_rotvec(np.outer(angles, axis)).as_matrix()  # (41, 3, 3)
    dm = rotation_change(r[:, None])[:, 0]
    np.testing.assert_allclose(dm[:-1], steps, rtol=1e-9, atol=1e-15)
    assert dm[-1] == 0


def test_limb_lengths_take_the_longest_child():
    """l_j is the longest link from j to a child; end sites get 0."""
    sk = Skeleton(
        ("a", "b", "c", "c_End", "b_End"),
        np.array([-1, 0, 0, 2, 1]),
        np.array([[0, 0, 0], [0.3, 0, 0], [0, 0.4, 0], [0, 0, 0.2], [0, 0.1, 0]]),
        np.array([False, False, False, True, True]),
    )
    np.testing.assert_allclose(limb_lengths(sk), [0.4, 0.1, 0.2, 0.0, 0.0])


def test_smoothing_matches_scipy_savgol():
    """The own Savitzky-Golay equals scipy.signal.savgol_filter(mode='interp')."""
    from scipy.signal import savgol_filter

    rng = np.random.default_rng(1)
    x = np.cumsum(rng.normal(size=(200, 4, 3)), axis=0)
    for fps, secs in ((120, 0.1), (60, 0.1), (60, 0.5), (30, 1.0)):
        w = int(round(fps * secs)) | 1
        got = smooth_positions(x, fps=fps, smooth_s=secs)
        want = savgol_filter(x, w, SAVGOL_POLYORDER, axis=0, mode="interp")
        np.testing.assert_allclose(got, want, atol=1e-10)


def test_straight_line_motion_has_zero_local_term():
    """Joints moving on straight lines (however fast, however they spin) carry no
    curvature, so no local information: exactly 0, with a warning, no NaN."""
    n, fps = 90, 30.0
    t = np.arange(n) / fps
    root = np.stack([0.3 * t + 0.8 * t**2, np.full(n, 1.0), np.full(n, -0.2)], axis=1)
    spin = _spin(n, 0.07, axis=(1.0, 0.0, 0.0))  # about the direction of travel
    c = _chain_character(root, spin, child_offset=(0.25, 0.0, 0.0), fps=fps)
    assert np.all(np.abs(rotation_change(c.local_rotations)[:-1, 0] - 0.07) < 1e-9)
    p = local_information(c, rest_speed=REST_SPEED)
    assert np.all(np.abs(p) < 1e-13)  # the child moves on the same line: kappa = 0
    scene = Scene([c], fps=fps, ground=-5.0)
    with pytest.warns(UserWarning) as caught:
        ent = pose_entropy(scene)
    assert any("local" in str(w.message) for w in caught)
    assert np.all(ent.local == 0) and np.all(np.isfinite(ent.total))


def test_static_clip_gives_a_defined_result_with_a_warning(motions_dir):
    """A clip that does not move: every term is 0 (not NaN), frame 0 is chosen, warned."""
    c = _load(motions_dir / "walk_run" / "02_01.bvh").characters[0].frames(100, 101)
    n = 60
    for name in ("positions", "rotations", "local_rotations", "local_quaternions"):
        setattr(c, name, np.repeat(getattr(c, name), n, axis=0))
    scene = Scene([c], fps=c.fps, ground=float(c.positions[..., 1].min()))
    with pytest.warns(UserWarning) as caught:
        sel = select_pose(scene, method="paper", k=3)
    messages = " | ".join(str(w.message) for w in caught)
    assert "static" in messages and "constant" in messages
    ent = sel.entropy
    for arr in (ent.local, ent.global_, ent.total):
        assert arr.shape == (n,) and np.all(arr == 0)
    assert sel.index == 0 and sel.indices[0] == 0
    # the feet rest on the floor for the whole clip: interactions, but no transitions
    assert ent.interactions.events and all(
        e.start == 0 and e.end == n - 1 for e in ent.interactions.events
    )


def test_one_sharp_reversal_is_where_the_pose_entropy_peaks():
    """A joint running out and back with one sharp turn (150 deg): the pose is the turn."""
    n, fps, turn = 121, 60.0, 70
    speed = 1.2 / fps
    heading_a = np.array([1.0, 0.0, 0.0])
    ang = math.radians(150.0)
    heading_b = np.array([math.cos(ang), 0.0, math.sin(ang)])
    steps = np.where(np.arange(n)[:, None] < turn, heading_a, heading_b) * speed
    root = np.r_[np.zeros((1, 3)), np.cumsum(steps[:-1], axis=0)] + [0.0, 1.0, 0.0]
    c = _chain_character(root, _spin(n, 0.02), fps=fps)
    scene = Scene([c], fps=fps, ground=-5.0)
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sel = select_pose(scene, method="paper", k=2)
    # no events anywhere: the global term is 0, as expected, without an alarm
    assert not [w for w in caught if "global" in str(w.message)]
    assert not sel.entropy.global_.any()
    assert sel.index == turn
    assert np.argmax(sel.entropy.local) == turn


def test_global_entropy_by_hand():
    """Two joints, one interacting half the time, one a tenth: -p log2 p at each
    onset/release of that joint; an interaction cut by the clip has no onset."""
    n = 20
    active = np.zeros((n, 2), bool)
    active[0:10, 0] = True  # joint 0: frames 0-9 (starts with the clip)
    active[12:14, 1] = True  # joint 1: frames 12-13
    h = global_entropy(active, [0, 1], [0, 12], [9, 13], mode="transitions")
    h0 = -0.5 * math.log2(0.5)
    h1 = -0.1 * math.log2(0.1)
    want = np.zeros(n)
    want[9] = h0  # release of joint 0 (its onset is the clip start: not an event)
    want[12] = want[13] = h1
    np.testing.assert_allclose(h, want)
    state = global_entropy(active, [0, 1], [0, 12], [9, 13], mode="state")
    np.testing.assert_allclose(state, active @ [h0, h1])
    with pytest.raises(ValueError, match="mode"):
        global_entropy(active, [], [], [], mode="onsets")


def test_minmax_constant_is_zero_with_warning():
    """A constant term normalises to 0, never NaN."""
    with pytest.warns(UserWarning, match="constant"):
        out = minmax(np.full(7, 3.5), name="x")
    assert np.all(out == 0)
    np.testing.assert_allclose(minmax(np.array([2.0, 4.0, 3.0])), [0.0, 1.0, 0.5])


def test_local_entropy_sums_information_to_one():
    """-p log2 p of p normalised over frames (eq. 5); all-zero information gives zeros."""
    info = np.array([0.0, 1.0, 3.0, 0.0])
    p = info / 4.0
    want = np.where(p > 0, -p * np.log2(np.where(p > 0, p, 1)), 0)
    np.testing.assert_allclose(local_entropy(info), want)
    assert np.all(local_entropy(np.zeros(5)) == 0)


def test_top_peaks_are_distinct_local_maxima():
    """Peaks come best first, at least min_separation apart, and only local maxima
    (the shoulder of the best peak never counts as a second pose)."""
    v = np.zeros(100)
    v[20], v[21], v[22], v[23] = 5.0, 4.9, 4.8, 4.7  # one peak with a long shoulder
    v[40], v[70], v[75] = 3.0, 2.0, 2.5
    assert top_peaks(v, 3, min_separation=10) == [20, 40, 75]
    assert top_peaks(v, 5, min_separation=10)[:3] == [20, 40, 75]
    assert top_peaks(v, 3, min_separation=1)[:3] == [20, 40, 75]
    assert top_peaks(v, 2, min_separation=30) == [20, 75]
    assert top_peaks(v, 1, min_separation=30) == [20]


def test_weights_steer_the_choice(motions_dir):
    """w_global = 0 picks the local maximum; w_local = 0 the global maximum."""
    scene = _load(motions_dir / "dance" / "05_06.bvh")
    only_local = _quiet(select_pose, scene, method="paper", w_global=0.0)
    only_global = _quiet(select_pose, scene, method="paper", w_local=0.0)
    assert only_local.index == int(np.argmax(only_local.entropy.local))
    assert only_global.index == int(np.argmax(only_global.entropy.global_))
    assert only_local.index != only_global.index


@pytest.mark.parametrize("fps", [30, 60, 120])
def test_synthetic_jump_events_are_at_takeoff_and_landing(fps):
    """In the synthetic jump the feet leave at JUMP_TAKEOFF_S and land at
    JUMP_LANDING_S: every spike of the global term is within 0.1 s of one of them
    (the ball of the foot lands first, the heel ~0.08 s later), and both have one."""
    scene = synth.synth_scene("jump", fps=fps)
    ent = _quiet(pose_entropy, scene)
    spikes = np.flatnonzero(ent.global_ > 0) / scene.fps
    truth = np.array([synth.JUMP_TAKEOFF_S, synth.JUMP_LANDING_S])
    assert np.all(np.min(np.abs(spikes[:, None] - truth[None]), axis=1) <= 0.1 + 1e-9)
    assert np.all(np.min(np.abs(spikes[:, None] - truth[None]), axis=0) <= 1.0 / fps + 1e-9)


# --------------------------------------------------------------------------- invariance


def _invariance_scenes(motions_dir):
    yield _load(motions_dir / "walk_run" / "02_01.bvh")
    yield _load(motions_dir / "dance" / "05_06.bvh")
    yield _load(motions_dir / "soccer" / "10_01.bvh")
    yield _load([motions_dir / p for p in SALSA_PAIRS[1]], fps=60)
    yield synth.synth_scene("push", fps=30)


def test_choice_is_invariant_to_yaw_translation_and_units(motions_dir):
    """Rotating the scene about the vertical, moving it, or changing its unit (metres
    to centimetres to inches) leaves the selected frames unchanged."""
    for scene in _invariance_scenes(motions_dir):
        base = _quiet(select_pose, scene, method="paper")
        for kw in (
            {"yaw_deg": 37.0},
            {"yaw_deg": -120.0, "offset": (3.0, 0.4, -7.5)},
            {"scale": 100.0},
            {"scale": 1 / 0.0254, "yaw_deg": 90.0},
        ):
            moved = _quiet(select_pose, scene.transformed(**kw), method="paper")
            assert moved.indices == base.indices, (scene.name, kw)
            np.testing.assert_allclose(moved.entropy.total, base.entropy.total, atol=1e-6)


# --------------------------------------------------------------------------- reference


def reference_smooth(x, fps, smooth_s):
    """Savitzky-Golay by one np.polyfit per frame (the ends from the first/last window)."""
    n = x.shape[0]
    w = int(round(smooth_s * fps))
    w += 1 - w % 2
    w = min(w, n - 1 + n % 2)
    if smooth_s <= 0 or w <= SAVGOL_POLYORDER:
        return x.copy()
    h = w // 2
    flat = x.reshape(n, -1)
    out = np.empty_like(flat)
    t = np.arange(w, dtype=float)
    for i in range(n):
        a = min(max(i - h, 0), n - w)
        coef = np.polyfit(t, flat[a : a + w], SAVGOL_POLYORDER)  # (3, columns)
        u = float(i - a)
        out[i] = (coef[0] * u + coef[1]) * u + coef[2]
    return out.reshape(x.shape)


def reference_local_information(c, rest_speed):
    lengths = np.linalg.norm(c.skeleton.offsets, axis=1)
    ell = np.zeros(c.n_joints)
    for j, p in enumerate(c.parents):
        if p >= 0:
            ell[p] = max(ell[p], lengths[j])
    x = reference_smooth(c.positions, c.fps, SMOOTH_S)
    floor = rest_speed / c.fps
    p = np.zeros(c.n_frames)
    for i in range(1, c.n_frames - 1):
        e0, e1 = x[i] - x[i - 1], x[i + 1] - x[i]
        n0, n1 = np.linalg.norm(e0, axis=1), np.linalg.norm(e1, axis=1)
        theta = np.arctan2(np.linalg.norm(np.cross(e0, e1), axis=1), np.sum(e0 * e1, axis=1))
        kappa = np.where((n0 >= floor) & (n1 >= floor), np.sin(theta / 2), 0.0)
        rel = np.transpose(c.local_rotations[i], (0, 2, 1)) @ c.local_rotations[i + 1]
        dm = Rotation.from_matrix(rel).magnitude()
        p[i] = np.sum(ell * dm * kappa)
    return p


def reference_scan(near, rel, m, tol):
    """The plain rule, frame by frame, then back-to-back pieces joined."""
    n_f, n_j = near.shape
    found = []
    for j in range(n_j):
        f = 0
        while f <= n_f - m:
            if (
                near[f, j]
                and near[f : f + m, j].all()
                and all(np.linalg.norm(rel(j, f, f + k)) <= tol for k in range(1, m))
            ):
                g = f + m
                while g < n_f and near[g, j] and np.linalg.norm(rel(j, f, g)) <= tol:
                    g += 1
                if found and found[-1][0] == j and found[-1][2] == f - 1:
                    found[-1] = (j, found[-1][1], g - 1)
                else:
                    found.append((j, f, g - 1))
                f = g
            else:
                f += 1
    return found


def reference_interactions(scene):
    """Events per character as (joint, object, start, end), from a per-frame loop."""
    k = float(np.mean([c.height for c in scene.characters])) / 1.70  # stature scale
    tol = DEFAULT_TOLERANCES
    m = max(2, math.ceil(tol.min_duration * scene.fps - 1e-9))
    out = []
    for c in scene.characters:
        x = c.positions
        events = []
        near = np.zeros((c.n_frames, c.n_joints), bool)
        for f in range(c.n_frames):
            near[f] = x[f, :, 1] - scene.ground <= tol.ground_distance * k
        for j, s, e in reference_scan(
            near, lambda j, s, g, x=x: x[g, j] - x[s, j], m, tol.displacement * k
        ):
            events.append((j, "ground", s, e))
        for other in scene.characters:
            if other is c:
                continue
            links, y, radii = other.skeleton.links, other.positions, bone_radii(other)
            near = np.zeros((c.n_frames, c.n_joints), bool)
            bone = np.zeros((c.n_frames, c.n_joints), int)
            for f in range(c.n_frames):
                a, b = y[f, links[:, 0]], y[f, links[:, 1]]  # (L, 3)
                ab = b - a
                ap = x[f][:, None] - a[None]  # (J, L, 3)
                t = np.sum(ap * ab, -1) / np.sum(ab * ab, -1)
                # nearest point on the segment; an end point exactly when outside, so
                # two bones meeting at a joint are equally near a point beyond it
                closest = np.where(
                    (t <= 0)[..., None],
                    a[None],
                    np.where((t >= 1)[..., None], b[None], a[None] + t[..., None] * ab[None]),
                )
                d = np.linalg.norm(x[f][:, None] - closest, axis=-1) - radii
                bone[f] = np.argmin(d, axis=1)
                near[f] = d.min(axis=1) <= tol.body_distance * k

            def rel(j, s, g, x=x, bone=bone, links=links, y=y, rot=other.rotations):
                p = links[bone[s, j], 0]
                return (rot[g, p].T @ (x[g, j] - y[g, p])) - (rot[s, p].T @ (x[s, j] - y[s, p]))

            for j, s, e in reference_scan(near, rel, m, tol.displacement * k):
                events.append((j, other.name, s, e))
        out.append(events)
    return out


def reference_pose_entropy(scene):
    """local, global, total per frame and the top-3 frames, by loops."""
    n_f = scene.n_frames
    rest = REST_SPEED * float(np.mean([c.height for c in scene.characters])) / 1.70
    local = np.zeros(n_f)
    for c in scene.characters:
        p = reference_local_information(c, rest)
        if p.max() > 1e-12:
            q = p / p.sum()
            local += np.array([-v * math.log2(v) if v > 0 else 0.0 for v in q])
    glob = np.zeros(n_f)
    for ci, events in enumerate(reference_interactions(scene)):
        c = scene.characters[ci]
        frames_active = np.zeros((n_f, c.n_joints), bool)
        for j, _, s, e in events:
            frames_active[s : e + 1, j] = True
        pj = frames_active.sum(axis=0) / n_f
        hj = [-v * math.log2(v) if v > 0 else 0.0 for v in pj]
        marks: dict[int, set] = {}
        for j, _, s, e in events:
            if s > 0:
                marks.setdefault(s, set()).add(j)
            if e < n_f - 1:
                marks.setdefault(e, set()).add(j)
        for i in range(n_f):
            glob[i] += sum(hj[j] for j in marks.get(i, ()))

    def norm(v):
        return (v - v.min()) / (v.max() - v.min()) if v.max() > v.min() else np.zeros_like(v)

    local, glob = norm(local), norm(glob)
    total = local + glob
    sep = int(round(0.3 * scene.fps))
    cands = [
        i
        for i in range(n_f)
        if (i == 0 or total[i] >= total[i - 1]) and (i == n_f - 1 or total[i] >= total[i + 1])
    ]
    cands.sort(key=lambda i: (-total[i], i))
    chosen = []
    for i in cands:
        if all(abs(i - c) >= sep for c in chosen):
            chosen.append(i)
        if len(chosen) == 3:
            break
    return local, glob, total, chosen


def _shared_scenes(motions_dir):
    for path in sorted(motions_dir.rglob("*.bvh")):
        rel = path.relative_to(motions_dir).as_posix()
        yield rel, [path], (60.0 if rel.startswith("two_person/") else None)
    for pair in SALSA_PAIRS:
        yield " + ".join(pair), [motions_dir / p for p in pair], 60.0


@pytest.mark.slow
def test_fast_equals_loop_reference_on_every_shared_clip(motions_dir, all_bvh):
    """On every BVH under the data folder and both salsa pairs: the vectorised pose
    entropy equals the per-frame loop reference to 1e-9, events and top-3 included."""
    checked = 0
    for label, paths, fps in _shared_scenes(motions_dir):
        scene = _load(paths, fps=fps)
        sel = _quiet(select_pose, scene, method="paper", k=3)
        local, glob, total, frames = reference_pose_entropy(scene)
        ent = sel.entropy
        np.testing.assert_allclose(ent.local, local, atol=1e-9, err_msg=label)
        np.testing.assert_allclose(ent.global_, glob, atol=1e-9, err_msg=label)
        np.testing.assert_allclose(ent.total, total, atol=1e-9, err_msg=label)
        assert sel.indices == frames, label
        checked += 1
    assert checked == len(all_bvh) + len(SALSA_PAIRS)


def test_synthetic_clips_pass_the_checks_without_shared_data():
    """Without ../shared: on every synthetic scene the vectorised (paper) pose entropy equals the
    loop reference (1e-9, top-3 and events included), and the choice is invariant to
    yaw, translation and unit (up to the order of exactly tied peaks)."""
    for name in synth.SCENES:
        scene = synth.synth_scene(name, fps=30)
        sel = _quiet(select_pose, scene, method="paper", k=3)
        local, glob, total, frames = reference_pose_entropy(scene)
        np.testing.assert_allclose(sel.entropy.local, local, atol=1e-9, err_msg=name)
        np.testing.assert_allclose(sel.entropy.global_, glob, atol=1e-9, err_msg=name)
        np.testing.assert_allclose(sel.entropy.total, total, atol=1e-9, err_msg=name)
        assert sel.indices == frames, name
        ref = reference_interactions(scene)
        for ci in range(scene.n_characters):
            got = sorted(
                (e.joint, e.object, e.start, e.end)
                for e in sel.entropy.interactions.for_character(ci)
            )
            assert got == sorted(ref[ci]), name
        if name == "idle":
            continue  # constant entropy: the first frame, whatever the transform
        for kw in (
            {"yaw_deg": -120.0, "offset": (3.0, 0.4, -7.5)},
            {"scale": 1 / 0.0254, "yaw_deg": 90.0},
        ):
            moved = _quiet(select_pose, scene.transformed(**kw), method="paper")
            np.testing.assert_allclose(moved.entropy.total, sel.entropy.total, atol=1e-6)
            # the same poses; a periodic synthetic clip ties its peaks, so their order may
            # swap, never their values
            assert sorted(moved.indices) == sorted(sel.indices), (name, kw)
            np.testing.assert_allclose(total[moved.indices], total[sel.indices], atol=1e-6)


def test_fast_events_equal_reference_events(motions_dir):
    """The interaction events themselves (joint, object, start, end) match the loop
    reference on a walk and a salsa pair (where body contacts happen)."""
    for paths, fps in (
        ([motions_dir / "walk_run" / "131_01.bvh"], None),
        ([motions_dir / p for p in SALSA_PAIRS[0]], 60.0),
    ):
        scene = _load(paths, fps=fps)
        fast = _quiet(pose_entropy, scene).interactions
        ref = reference_interactions(scene)
        for ci in range(scene.n_characters):
            got = sorted((e.joint, e.object, e.start, e.end) for e in fast.for_character(ci))
            assert got == sorted(ref[ci])


def test_local_term_needs_no_quaternions(motions_dir):
    """A character built without quaternions (only matrices) gets the same local term:
    the matrices are converted, and the result equals the loaded character's."""
    import dataclasses

    c = _load(motions_dir / "walk_run" / "131_01.bvh").characters[0]
    bare = dataclasses.replace(c, local_quaternions=None)
    np.testing.assert_allclose(
        local_information(bare), local_information(c), rtol=1e-12, atol=1e-15
    )
    assert local_information(c).max() > 0


def test_pose_params_are_the_pose_options():
    """take_snapshot(scene, pose=PoseParams(...)) runs select_pose with those options, and
    a flat options table (a study config's ``selection``) gives the same parameter
    objects by field name; Snapshot.options records the method and its parameters."""
    from snapcore.pipeline import ViewParams, snapshot_params, take_snapshot
    from snapcore.select.pose_methods import PoseParams, select_pose

    scene = synth.synth_scene("walk", fps=30)
    paper = dict(pose_method="paper", w_local=0.5, smooth_s=0.0)
    a = take_snapshot(scene, pose=PoseParams(k=2, **paper), view=None)
    pose, view = snapshot_params({"k": 2, **paper, "window_s": 0.25, "n_views": 162})
    assert pose == PoseParams(k=2, **paper) and view == ViewParams(window_s=0.25, n_views=162)
    b = take_snapshot(scene, pose=pose, view=None)
    direct = _quiet(select_pose, scene, method="paper", k=2, w_local=0.5, smooth_s=0.0)
    assert a.indices == b.indices == direct.indices and len(a.indices) == 2
    np.testing.assert_array_equal(a.pose.entropy.total, b.pose.entropy.total)
    np.testing.assert_array_equal(a.pose.entropy.total, direct.entropy.total)
    fields = set(PoseParams(pose_method="paper").kwargs()) - {"tolerances", "method"}
    assert fields | {"pose_method", "contact_tolerances"} == set(a.options)
    assert a.options["w_local"] == 0.5 and a.options["k"] == 2
    assert a.options["pose_method"] == "paper"
    assert a.view_params is None and a.view is None  # view=None: no view stage


def test_paper_options_are_refused_once_at_construction():
    """A paper-only option with another method fails when the PoseParams is made (not
    later, not silently dropped), and select_pose's keywords follow the same rule."""
    from snapcore.select.pose_methods import PaperOptionError, PoseParams, select_pose

    with pytest.raises(PaperOptionError, match="w_local apply to the 'paper' pose method only"):
        PoseParams(w_local=0.5)
    with pytest.raises(PaperOptionError, match="events, smooth_s .* not 'fastest'") as err:
        PoseParams(pose_method="fastest", smooth_s=0.0, events="state")
    assert err.value.names == ("events", "smooth_s") and isinstance(err.value, ValueError)
    PoseParams(pose_method="story", w_local=1.0)  # a default value is not a choice
    assert PoseParams(pose_method="paper", w_local=0.5).kwargs()["w_local"] == 0.5
    scene = synth.synth_scene("walk", fps=30)
    with pytest.raises(PaperOptionError, match="rest_speed"):
        select_pose(scene, method="middle", rest_speed=0.2)


def test_snapshot_params_name_an_unknown_key():
    """A key that is a field of neither parameter object is one ValueError naming it
    (an old keyword spelling, a typo); take_snapshot takes only parameter objects."""
    from snapcore.pipeline import snapshot_params, take_snapshot

    with pytest.raises(ValueError, match=r"^unknown selection option\(s\) top_k \(pose: "):
        snapshot_params({"k": 2, "top_k": 3})
    scene = synth.synth_scene("walk", fps=30)
    with pytest.raises(TypeError, match="view must be a ViewParams"):
        take_snapshot(scene, view=True)  # the old boolean spelling
    with pytest.raises(TypeError, match="pose must be a PoseParams"):
        take_snapshot(scene, pose={"k": 2})
    with pytest.raises(TypeError):
        take_snapshot(scene, k=2)  # type: ignore[call-arg]
