"""Cell-list detection equals brute force; the Verlet skin list equals a fresh search."""

import numpy as np
import pytest

from asphalt_nscd.nscd import detection

#: every test here also runs as Python (tests/unit/test_nscd_kernels_python.py)
pytestmark = pytest.mark.kernels


def _brute(pos, rad, max_gap):
    out = set()
    for a in range(len(pos)):
        for b in range(a + 1, len(pos)):
            if np.linalg.norm(pos[a] - pos[b]) - rad[a] - rad[b] < max_gap:
                out.add((a, b))
    return out


def test_sphere_pairs_match_brute_force():
    rng = np.random.default_rng(3)
    pos = rng.uniform(0, 0.05, (300, 3))
    rad = rng.uniform(1e-3, 4e-3, 300)
    i, j, gap = detection.sphere_pairs(pos, rad, 1e-3)
    assert set(zip(i.tolist(), j.tolist())) == _brute(pos, rad, 1e-3)
    d = np.linalg.norm(pos[i] - pos[j], axis=1) - rad[i] - rad[j]
    np.testing.assert_allclose(gap, d)


def test_plate_pairs_and_frames():
    pos = np.array([[0.0, 0.0, 0.011], [0.0, 0.0, 0.05]])
    rad = np.array([0.01, 0.01])
    ci, cj, gap, frame = detection.detect_contacts(pos, rad, np.zeros((1, 3)), np.array([[0, 0, 1.0]]), 0.002)
    assert ci.tolist() == [0] and cj.tolist() == [-1]
    np.testing.assert_allclose(gap, [0.001])
    f = frame[0]
    np.testing.assert_allclose(f @ f.T, np.eye(3), atol=1e-14)
    np.testing.assert_allclose(f[0], [0, 0, 1])


def test_candidate_list_with_skin_equals_fresh_search():
    rng = np.random.default_rng(5)
    pos = rng.uniform(0, 0.03, (200, 3))
    rad = rng.uniform(1e-3, 2e-3, 200)
    pts = np.zeros((1, 3))
    nrm = np.array([[0, 0, 1.0]])
    cl = detection.CandidateList(5e-4)
    for _ in range(20):
        pos += rng.normal(0, 5e-5, pos.shape)
        a = cl.contacts(pos, rad, pts, nrm)
        b = detection.detect_contacts(pos, rad, pts, nrm, 5e-4)
        assert set(zip(a[0].tolist(), a[1].tolist())) == set(zip(b[0].tolist(), b[1].tolist()))
    assert cl.n_searches < 20
