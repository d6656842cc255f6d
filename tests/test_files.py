"""Data and model files: round trips to the last bit, damaged files refused."""

import json

import numpy as np
import pytest

import lpvid
from lpvid.testing import noisy_data, random_lpv


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
@pytest.mark.parametrize("Ts", [0.01, None])
def test_data_round_trip(tmp_path, rng, suffix, Ts):
    model = random_lpv(rng, n=2, r=2, l=3, nb=1, Ts=Ts)
    data = noisy_data(model, np.array([0.0, 0.5, 1.0]), np.linspace(1, 40, 6), rng)
    path = data.save(tmp_path / f"d{suffix}")
    back = lpvid.FrfData.load(path)
    for name in ("p", "freqs_hz", "G", "sigma"):
        np.testing.assert_array_equal(getattr(back, name), getattr(data, name))
    assert back.Ts == data.Ts


def test_single_point_siso_mat_round_trip(tmp_path):
    data = lpvid.FrfData([2.0], [1.0, 2.0], np.ones((1, 2, 1, 1)), Ts=0.1)
    back = lpvid.FrfData.load(data.save(tmp_path / "one.mat"))
    assert back.G.shape == (1, 2, 1, 1)
    np.testing.assert_array_equal(back.p, data.p)


def test_data_files_of_other_kinds_are_refused(tmp_path):
    with pytest.raises(ValueError, match="path"):
        lpvid.FrfData([0.0], [1.0], np.ones((1, 1))).save(tmp_path / "x.csv")
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip file")
    with pytest.raises(ValueError, match="bad.npz"):
        lpvid.FrfData.load(bad)
    np.savez(tmp_path / "partial.npz", p=np.zeros(2))
    with pytest.raises(ValueError, match="freqs_hz"):
        lpvid.FrfData.load(tmp_path / "partial.npz")


@pytest.mark.parametrize(
    "basis", [lpvid.Polynomial(3, domain=(24, 48)), lpvid.Legendre(2, domain=(-1, 2))]
)
def test_model_round_trip_is_exact(tmp_path, rng, basis):
    nb = len(basis)
    m = lpvid.LpvModel(
        rng.normal(size=(nb + 1, 4, 4)) / 3,
        rng.normal(size=(nb + 1, 4, 2)),
        rng.normal(size=(nb + 1, 3, 4)),
        rng.normal(size=(nb + 1, 3, 2)),
        basis,
        Ts=1 / 3000,
        info={"coherent_form": "observability", "condition": 12.5},
    )
    back = lpvid.LpvModel.load(m.save(tmp_path / "m.json"))
    assert back.info == m.info
    assert back == m
    np.testing.assert_array_equal(back.theta, m.theta)
    assert back.p_range == m.p_range
    assert back.Ts == m.Ts


def test_damaged_or_foreign_model_files_are_refused(tmp_path, rng):
    m = random_lpv(rng, n=2, r=1, l=1, nb=1)
    path = m.save(tmp_path / "m.json")
    text = path.read_text()
    doc = json.loads(text)

    damaged = tmp_path / "damaged.json"
    doc2 = json.loads(text)
    doc2["content"]["A"][0][0][0] += 1e-9
    damaged.write_text(json.dumps(doc2))
    with pytest.raises(ValueError, match="damaged"):
        lpvid.LpvModel.load(damaged)

    truncated = tmp_path / "truncated.json"
    truncated.write_text(text[: len(text) // 2])
    with pytest.raises(ValueError, match="not an lpvid model file"):
        lpvid.LpvModel.load(truncated)

    future = tmp_path / "future.json"
    future.write_text(json.dumps({**doc, "version": 99}))
    with pytest.raises(ValueError, match="version"):
        lpvid.LpvModel.load(future)

    foreign = tmp_path / "foreign.json"
    foreign.write_text(json.dumps({"hello": "world"}))
    with pytest.raises(ValueError, match="not an lpvid model file"):
        lpvid.LpvModel.load(foreign)


def test_custom_basis_model_cannot_be_saved(tmp_path):
    basis = lpvid.CustomBasis([np.sin])
    m = lpvid.LpvModel(np.zeros((2, 1, 1)), np.ones((2, 1, 1)), np.ones((2, 1, 1)), basis=basis)
    with pytest.raises(TypeError, match="CustomBasis"):
        m.save(tmp_path / "m.json")
    assert not (tmp_path / "m.json").exists()
    assert list(tmp_path.iterdir()) == []


def test_failed_write_leaves_the_old_file(tmp_path, rng):
    m = random_lpv(rng, n=2, r=1, l=1, nb=1)
    path = m.save(tmp_path / "m.json")
    before = path.read_bytes()
    bad = lpvid.LpvModel(
        np.zeros((2, 1, 1)),
        np.ones((2, 1, 1)),
        np.ones((2, 1, 1)),
        basis=lpvid.CustomBasis([np.sin]),
    )
    with pytest.raises(TypeError):
        bad.save(path)
    assert path.read_bytes() == before


def test_written_files_have_the_usual_permissions(tmp_path, rng):
    import os
    import stat

    umask = os.umask(0o022)
    try:
        path = random_lpv(rng, n=2, r=1, l=1, nb=1).save(tmp_path / "m.json")
    finally:
        os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
