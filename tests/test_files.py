"""Data and model files: round trips to the last bit, damaged files refused."""

import json
import re

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
    with pytest.raises(ValueError, match=r"^path: expected a \.npz or \.mat file, got 'x\.csv'"):
        lpvid.FrfData([0.0], [1.0], np.ones((1, 1))).save(tmp_path / "x.csv")
    bad = tmp_path / "bad.npz"
    bad.write_bytes(b"not a zip file")
    with pytest.raises(ValueError, match=r"^path: bad\.npz: not a readable \.npz file"):
        lpvid.FrfData.load(bad)
    np.savez(tmp_path / "partial.npz", p=np.zeros(2))
    with pytest.raises(ValueError, match=r"^path: partial\.npz lacks the variables freqs_hz, G$"):
        lpvid.FrfData.load(tmp_path / "partial.npz")


ROUND_TRIP_BASES = {
    "poly": lpvid.Polynomial(3, domain=(24, 48)),
    "legendre": lpvid.Legendre(2, domain=(-1, 2)),
    "poly-2p": lpvid.Polynomial(2, domain=[(0, 1), (10, 30)]),
    "legendre-2p": lpvid.Legendre(2, domain=[(0, 1), (10, 30)]),
    "poly-2p-raw": lpvid.Polynomial(2, n_params=2),
    "lti": lpvid.Polynomial(0),
}


def mat_variables(path):
    from scipy.io import loadmat

    return {k: v for k, v in loadmat(path).items() if not k.startswith("__")}


def round_trip_model(rng, basis, Ts):
    nb = len(basis)
    p_range = [(0.0, 1.0), (10.0, 30.0)] if basis.n_params == 2 else (-0.5, 0.25)
    return lpvid.LpvModel(
        rng.normal(size=(nb + 1, 4, 4)) / 3,
        rng.normal(size=(nb + 1, 4, 2)),
        rng.normal(size=(nb + 1, 3, 4)),
        rng.normal(size=(nb + 1, 3, 2)),
        basis,
        Ts=Ts,
        p_range=p_range,
        info={"coherent_form": "observability", "condition": 12.5},
    )


def assert_same_model(back, m):
    for name, arr in m.matrices().items():
        got = getattr(back, name)
        assert got.shape == arr.shape and got.dtype == np.float64, name
        # to the last bit: the same bytes
        assert got.tobytes() == arr.tobytes(), name
    assert back.Ts == m.Ts and (back.Ts is None) == (m.Ts is None)
    assert back.basis.to_dict() == m.basis.to_dict()
    assert back.basis.names == m.basis.names
    assert back.p_range == m.p_range


@pytest.mark.parametrize("suffix", [".json", ".mat"])
@pytest.mark.parametrize("Ts", [1 / 3000, None], ids=["discrete", "continuous"])
@pytest.mark.parametrize("basis", ROUND_TRIP_BASES.values(), ids=ROUND_TRIP_BASES.keys())
def test_model_round_trip_is_exact(tmp_path, rng, basis, Ts, suffix):
    m = round_trip_model(rng, basis, Ts)
    back = lpvid.LpvModel.load(m.save(tmp_path / f"m{suffix}"))
    assert_same_model(back, m)
    assert back.info == m.info


@pytest.mark.parametrize("Ts", [1 / 3000, None], ids=["discrete", "continuous"])
@pytest.mark.parametrize("basis", ROUND_TRIP_BASES.values(), ids=ROUND_TRIP_BASES.keys())
def test_mat_file_holds_the_model_as_matlab_arrays(tmp_path, rng, basis, Ts):
    """The MATLAB variables themselves (not the embedded JSON) hold the model."""
    m = round_trip_model(rng, basis, Ts)
    raw = mat_variables(m.save(tmp_path / "m.mat"))
    for name, arr in m.matrices().items():
        # X(:,:,k+1) in MATLAB is X[k] in lpvid
        np.testing.assert_array_equal(np.moveaxis(raw[name], -1, 0), arr)
    if Ts is None:
        assert raw["Ts"].size == 0
    else:
        assert raw["Ts"].item() == Ts
    assert raw["basis_kind"].item() == basis.kind
    assert raw["basis_degree"].item() == basis.degree
    assert raw["basis_n_params"].item() == basis.n_params
    if basis.domain is None:
        assert raw["basis_domain"].size == 0
    else:
        np.testing.assert_array_equal(raw["basis_domain"], basis.domain)
    assert [str(x.item()) for x in raw["basis_names"].ravel()] == basis.names
    np.testing.assert_array_equal(raw["p_range"], np.atleast_2d(m.p_range))
    # without the embedded copy, the arrays alone give the same model
    del raw["lpvid_model"]
    savemat(tmp_path / "arrays.mat", raw)
    assert_same_model(lpvid.LpvModel.load(tmp_path / "arrays.mat"), m)


def savemat(path, variables):
    from scipy.io import savemat as write

    write(path, variables)


@pytest.mark.parametrize(
    ("variable", "edit"),
    [
        ("A", lambda v: v + np.eye(v.shape[0])[:, :, None] * 1e-12),
        ("B", lambda v: -v),
        ("C", lambda v: np.float32(v).astype(float)),
        ("D", lambda v: 2 * v),
        ("Ts", lambda v: np.array([[0.5]])),
        ("basis_domain", lambda v: v + 1.0),
        ("basis_degree", lambda v: v - 1),
        ("p_range", lambda v: np.array([[-0.5, 0.3]])),
    ],
)
def test_mat_file_edited_after_saving_is_refused(tmp_path, rng, variable, edit):
    basis = lpvid.Polynomial(2, domain=(-1, 1))
    m = round_trip_model(rng, basis, 0.01)
    raw = mat_variables(m.save(tmp_path / "m.mat"))
    raw[variable] = edit(raw[variable])
    if variable == "basis_degree":  # fewer functions: drop the last coefficients
        for x in "ABCD":
            raw[x] = raw[x][:, :, :-1]
        raw["basis_names"] = raw["basis_names"][:, :-1]
    savemat(tmp_path / "edited.mat", raw)
    differ = "ABCD" if variable == "basis_degree" else variable
    with pytest.raises(ValueError, match=r"^path: edited\.mat: the MATLAB variables? ") as exc:
        lpvid.LpvModel.load(tmp_path / "edited.mat")
    named = re.match(r".* variables? (.*?) differs? from", str(exc.value)).group(1).split(", ")
    assert variable in named
    assert set(named) <= {variable, *differ}


def test_mat_file_with_basis_names_of_another_basis_is_refused(tmp_path, rng):
    m = round_trip_model(rng, lpvid.Legendre(2, domain=(-1, 1)), 0.01)
    raw = mat_variables(m.save(tmp_path / "m.mat"))
    raw["basis_names"] = np.array(["s", "s^2"], dtype=object)
    savemat(tmp_path / "edited.mat", raw)
    with pytest.raises(ValueError, match=r"^path: edited\.mat: basis_names: .*do not match"):
        lpvid.LpvModel.load(tmp_path / "edited.mat")


def test_mat_file_written_in_matlab_is_read_from_its_arrays(tmp_path):
    """A model written by hand (MATLAB drops trailing singleton dimensions; no D)."""
    A = np.array([[0.5, 0.1], [0.0, 0.7]])  # n x n: Nb = 0
    savemat(
        tmp_path / "hand.mat",
        {
            "A": A,
            "B": np.array([[1.0], [0.5]]),
            "C": np.array([[1.0, 0.0]]),
            "Ts": 0.1,
            "basis_kind": "polynomial",
            "basis_degree": 0.0,
        },
    )
    m = lpvid.LpvModel.load(tmp_path / "hand.mat")
    assert m.shape == (2, 1, 1, 0) and m.Ts == 0.1
    np.testing.assert_array_equal(m.A[0], A)
    np.testing.assert_array_equal(m.D, np.zeros((1, 1, 1)))
    assert m.p_range is None and m.info == {}


def test_mat_file_without_a_model_is_refused(tmp_path):
    savemat(tmp_path / "other.mat", {"x": np.ones(3)})
    with pytest.raises(ValueError, match=r"^path: other\.mat is not an lpvid model file"):
        lpvid.LpvModel.load(tmp_path / "other.mat")
    savemat(tmp_path / "partial.mat", {"A": np.ones((1, 1)), "basis_kind": "polynomial"})
    with pytest.raises(ValueError, match=r"^path: partial\.mat: B: missing"):
        lpvid.LpvModel.load(tmp_path / "partial.mat")


def test_damaged_or_foreign_model_files_are_refused(tmp_path, rng):
    m = random_lpv(rng, n=2, r=1, l=1, nb=1)
    path = m.save(tmp_path / "m.json")
    text = path.read_text()
    doc = json.loads(text)

    damaged = tmp_path / "damaged.json"
    doc2 = json.loads(text)
    doc2["content"]["A"][0][0][0] += 1e-9
    damaged.write_text(json.dumps(doc2))
    with pytest.raises(
        ValueError, match=r"^path: damaged\.json is damaged \(its checksum does not match"
    ):
        lpvid.LpvModel.load(damaged)

    truncated = tmp_path / "truncated.json"
    truncated.write_text(text[: len(text) // 2])
    with pytest.raises(
        ValueError, match=r"^path: truncated\.json is not an lpvid model file \(not valid JSON"
    ):
        lpvid.LpvModel.load(truncated)

    future = tmp_path / "future.json"
    future.write_text(json.dumps({**doc, "version": 99}))
    with pytest.raises(
        ValueError,
        match=r"^path: future\.json has model file version 99; this lpvid reads versions 1 to 2",
    ):
        lpvid.LpvModel.load(future)

    foreign = tmp_path / "foreign.json"
    foreign.write_text(json.dumps({"hello": "world"}))
    with pytest.raises(ValueError, match=r"^path: foreign\.json is not an lpvid model file$"):
        lpvid.LpvModel.load(foreign)


def test_custom_basis_model_cannot_be_saved(tmp_path):
    basis = lpvid.CustomBasis([np.sin])
    m = lpvid.LpvModel(np.zeros((2, 1, 1)), np.ones((2, 1, 1)), np.ones((2, 1, 1)), basis=basis)
    with pytest.raises(
        TypeError, match=r"^CustomBasis holds Python functions, which cannot be written to a file"
    ):
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
