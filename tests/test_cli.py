"""The command line: every misuse is one line on stderr and exit code 2."""

import json
import re
import warnings

import numpy as np
import pytest

import lpvid
from lpvid.cli import main
from lpvid.pipeline.between import RESAMPLED_SCALE


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Data files: the gantry (5 points, 2 outputs x 1 input, Ts = 0.5 ms) and misfits."""
    folder = tmp_path_factory.mktemp("cli")
    ds = lpvid.datasets.gantry(n_lines=40)
    data, val = ds.identification, ds.validation
    data.save(folder / "id.npz")
    val.save(folder / "val.mat")
    lpvid.FrfData(val.p, val.freqs_hz, val.G, val.sigma, Ts=1e-3).save(folder / "val-ts.npz")
    lpvid.FrfData(val.p, val.freqs_hz, val.G, val.sigma, Ts=None).save(folder / "val-ct.npz")
    lpvid.FrfData(val.p, val.freqs_hz, val.G[:, :, :1], val.sigma[:, :, :1], Ts=val.Ts).save(
        folder / "val-1out.npz"
    )
    G2 = np.concatenate([val.G, val.G], axis=3)
    lpvid.FrfData(val.p, val.freqs_hz, G2, Ts=val.Ts).save(folder / "val-2in.npz")
    lpvid.FrfData(val.p + 10, val.freqs_hz, val.G, val.sigma, Ts=val.Ts).save(
        folder / "val-beyond.npz"
    )
    p2 = np.stack([val.p, val.p[::-1]], axis=1)
    lpvid.FrfData(p2, val.freqs_hz, val.G, val.sigma, Ts=val.Ts).save(folder / "val-2p.npz")
    p2 = np.stack([data.p, data.p[::-1]], axis=1)
    lpvid.FrfData(p2, data.freqs_hz, data.G, data.sigma, Ts=data.Ts).save(folder / "id-2p.npz")
    (folder / "data.csv").write_text("p,f,G\n1,2,3\n")
    (folder / "garbage.npz").write_bytes(b"PK\x03\x04 not really a zip file")
    np.savez(folder / "partial.npz", p=data.p, freqs_hz=data.freqs_hz)
    lpvid.LpvModel([[0.5]], [[1.0]], [[1.0]], Ts=1.0).save(folder / "model.json")
    (folder / "bad.toml").write_text('Ts = 0.0005\noutputs = ["y"]\n')
    G = data.G.copy()
    G[3, 7, 1, 0] = np.nan
    np.savez(folder / "nan.npz", p=data.p, freqs_hz=data.freqs_hz, G=G, Ts=data.Ts)
    (folder / "script.py").write_text("print('not data')\n")
    (folder / "a-file").write_text("in the way")
    (folder / "a-folder").mkdir()
    return folder


FIT = ["fit", "{f}/id.npz", "--order", "6", "--out", "{out}"]
VAL = ["--validation", "{f}/val.mat"]

# (id, argv, the option the one line must name)
MISUSE = [
    # the command itself
    ("no-command-args", ["fit"], "data"),
    ("unknown-command", ["frobnicate"], "COMMAND"),
    ("unknown-option", [*FIT, "--speed", "3"], "--speed"),
    ("demo-unknown-option", ["demo", "--fast"], "--fast"),
    ("demo-quiet-with-value", ["demo", "--quiet=yes"], "--quiet"),
    ("fit-no-figures-with-value", [*FIT, "--no-figures=1"], "--no-figures"),
    # demo
    ("demo-data-unknown", ["demo", "--data", "nope"], "--data"),
    ("demo-out-is-a-file", ["demo", "--out", "{f}/a-file", "--quiet"], "--out"),
    ("demo-out-under-a-file", ["demo", "--out", "{f}/a-file/sub", "--quiet"], "--out"),
    ("demo-out-empty", ["demo", "--out", "", "--quiet"], "--out"),
    # data
    ("data-missing", ["fit", "{f}/nothing.npz", "--order", "6", "--out", "{out}"], "data"),
    ("data-is-a-folder", ["fit", "{f}/a-folder", "--order", "6", "--out", "{out}"], "data"),
    ("data-other-format", ["fit", "{f}/data.csv", "--order", "6", "--out", "{out}"], "data"),
    ("data-unreadable", ["fit", "{f}/garbage.npz", "--order", "6", "--out", "{out}"], "data"),
    ("data-incomplete", ["fit", "{f}/partial.npz", "--order", "6", "--out", "{out}"], "data"),
    ("data-a-model-file", ["fit", "{f}/model.json", "--order", "6", "--out", "{out}"], "data"),
    (
        "data-with-a-nan",
        ["fit", "{f}/nan.npz", "--order", "6", "--out", "{out}"],
        "point 3, line 7",
    ),
    ("data-a-python-file", ["fit", "{f}/script.py", "--order", "6", "--out", "{out}"], ".toml"),
    # --order
    ("order-missing", ["fit", "{f}/id.npz", "--out", "{out}"], "--order"),
    ("order-zero", [*FIT[:3], "0", *FIT[4:]], "--order"),
    ("order-negative", [*FIT[:3], "-2", *FIT[4:]], "--order"),
    ("order-not-a-number", [*FIT[:3], "six", *FIT[4:]], "--order"),
    ("order-not-an-integer", [*FIT[:3], "2.5", *FIT[4:]], "--order"),
    # more parameters than residuals: refused before any computation
    ("order-too-high-for-the-data", [*FIT[:3], "30", *FIT[4:]], "--order"),
    ("order-beyond-the-subspace-step", [*FIT[:3], "999", *FIT[4:]], "--order"),
    # --basis
    ("basis-unknown", [*FIT, "--basis", "cubic:2"], "--basis"),
    ("basis-no-degree", [*FIT, "--basis", "poly"], "--basis"),
    ("basis-negative-degree", [*FIT, "--basis", "poly:-1"], "--basis"),
    ("basis-degree-not-a-number", [*FIT, "--basis", "legendre:two"], "--basis"),
    ("basis-too-many-functions", [*FIT, "--basis", "poly:5"], "--basis"),
    ("basis-huge-degree", [*FIT, "--basis", "legendre:100000"], "--basis"),
    (
        "basis-too-many-for-2-params",
        ["fit", "{f}/id-2p.npz", *FIT[2:], "--basis", "poly:2"],
        "--basis",
    ),
    # --domain
    ("domain-reversed", [*FIT, "--domain", "1", "0"], "--domain"),
    ("domain-empty", [*FIT, "--domain", "30", "30"], "--domain"),
    ("domain-nan", [*FIT, "--domain", "nan", "50"], "--domain"),
    ("domain-inf", [*FIT, "--domain", "0", "inf"], "--domain"),
    ("domain-one-number", [*FIT, "--domain", "30"], "--domain"),
    ("domain-not-numbers", [*FIT, "--domain", "a", "b"], "--domain"),
    ("domain-misses-the-data", [*FIT, "--domain", "30", "40"], "--domain"),
    (
        "domain-misses-the-validation",
        [*FIT, "--validation", "{f}/val-beyond.npz", "--domain", "24", "48"],
        "--domain",
    ),
    (
        "domain-for-2-params",
        ["fit", "{f}/id-2p.npz", *FIT[2:], "--basis", "poly:1", "--domain", "0", "1"],
        "--domain",
    ),
    # --gamma
    ("gamma-no-value", [*FIT, "--gamma"], "--gamma"),
    ("gamma-zero", [*FIT, "--gamma", "0.1", "0"], "--gamma"),
    ("gamma-negative", [*FIT, "--gamma", "-0.1"], "--gamma"),
    ("gamma-nan", [*FIT, "--gamma", "nan"], "--gamma"),
    ("gamma-inf", [*FIT, "--gamma", "inf"], "--gamma"),
    ("gamma-not-a-number", [*FIT, "--gamma", "small"], "--gamma"),
    # --fix
    ("fix-unknown-matrix", [*FIT, "--fix", "E"], "--fix"),
    ("fix-twice", [*FIT, "--fix", "D", "--fix", "D"], "--fix"),
    ("fix-everything", [*FIT, "--fix", "A", "--fix", "B", "--fix", "C", "--fix", "D"], "--fix"),
    # --validation
    ("validation-missing", [*FIT, "--validation", "{f}/nothing.mat"], "--validation"),
    ("validation-other-format", [*FIT, "--validation", "{f}/data.csv"], "--validation"),
    ("validation-unreadable", [*FIT, "--validation", "{f}/garbage.npz"], "--validation"),
    ("validation-other-outputs", [*FIT, "--validation", "{f}/val-1out.npz"], "--validation"),
    ("validation-other-inputs", [*FIT, "--validation", "{f}/val-2in.npz"], "--validation"),
    ("validation-other-Ts", [*FIT, "--validation", "{f}/val-ts.npz"], "--validation"),
    ("validation-continuous", [*FIT, "--validation", "{f}/val-ct.npz"], "--validation"),
    ("validation-2-params", [*FIT, "--validation", "{f}/val-2p.npz"], "--validation"),
    # --tolerance
    ("tolerance-negative", [*FIT, *VAL, "--tolerance", "-0.1"], "--tolerance"),
    ("tolerance-nan", [*FIT, *VAL, "--tolerance", "nan"], "--tolerance"),
    ("tolerance-inf", [*FIT, *VAL, "--tolerance", "inf"], "--tolerance"),
    ("tolerance-not-a-number", [*FIT, *VAL, "--tolerance", "ten"], "--tolerance"),
    ("tolerance-without-validation", [*FIT, "--tolerance", "0.2"], "--tolerance"),
    # --lines (measured files)
    ("lines-unknown", [*FIT, "--lines", "all"], "--lines"),
    ("lines-without-a-manifest", [*FIT, "--lines", "common"], "--lines"),
    ("data-bad-manifest", ["fit", "{f}/bad.toml", "--order", "6", "--out", "{out}"], "data"),
    # --suggest
    ("suggest-zero", [*FIT, "--suggest", "0"], "--suggest"),
    ("suggest-not-a-number", [*FIT, "--suggest", "two"], "--suggest"),
    ("suggest-more-than-the-grid", [*FIT, "--suggest", "100"], "--suggest"),
    # --resample
    ("resample-zero", [*FIT, "--resample", "0"], "--resample"),
    ("resample-not-a-number", [*FIT, "--resample", "five"], "--resample"),
    # --out
    ("out-missing", ["fit", "{f}/id.npz", "--order", "6"], "--out"),
    ("out-is-a-file", [*FIT[:5], "{f}/a-file"], "--out"),
    ("out-under-a-file", [*FIT[:5], "{f}/a-file/sub"], "--out"),
    ("out-empty", [*FIT[:5], ""], "--out"),
]


@pytest.mark.parametrize(("argv", "option"), [m[1:] for m in MISUSE], ids=[m[0] for m in MISUSE])
def test_misuse_is_one_line_naming_the_option_and_exit_code_2(
    files, tmp_path, capsys, argv, option
):
    argv = [a.format(f=files, out=tmp_path / "out") for a in argv]
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert code == 2, captured.err
    assert len(lines) == 1, captured.err
    assert re.match(r"^lpvid( fit| demo)?: error: ", lines[0]), lines[0]
    assert option in lines[0].split("error: ", 1)[1], lines[0]
    # refused before any computation: no stage of the pipeline started
    assert "local models" not in captured.out
    assert not (tmp_path / "out").exists()


def test_no_command_is_a_usage_error(capsys):
    """`lpvid` alone prints the help to stderr, says a command is needed, and exits 2."""
    assert main([]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "usage: lpvid" in captured.err
    assert (
        captured.err.splitlines()[-1] == "lpvid: error: a command is needed (demo, fit or select)"
    )


def test_fit_help_says_what_the_basis_holds_and_how_to_make_the_example(capsys):
    with pytest.raises(SystemExit):
        main(["fit", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "the constant and the powers" in text
    assert "default poly:2 (the demo's gantry uses poly:4)" in text
    assert "lpvid.datasets.gantry().identification.save('gantry.npz')" in text
    for suffix in (".npz", ".mat", ".toml"):
        assert suffix in text.split("positional arguments:")[1].split("options:")[0]


def test_order_too_high_names_the_largest_order_the_data_allow(files, tmp_path, capsys):
    argv = [a.format(f=files, out=tmp_path / "out") for a in FIT]
    argv[3] = "30"
    assert main(argv) == 2
    line = capsys.readouterr().err.strip()
    # poly:2 by default (Nb = 2): 3 (n^2 + 3 n + 2) free parameters for 2 outputs x
    # 1 input, less the n^2 of the state coordinates, against the 2 M real
    # equations of the M complex residuals.
    data = lpvid.FrfData.load(files / "id.npz")
    m = data.n_residuals
    largest = max(n for n in range(1, 40) if 3 * (n * n + 3 * n + 2) - n * n <= 2 * m)
    assert largest == 17
    assert f"at most order {largest}" in line


def test_fit_help_speaks_to_engineers(capsys):
    with pytest.raises(SystemExit):
        main(["fit", "--help"])
    text = capsys.readouterr().out
    for word in ("--order", "--basis", "--validation", "scheduling", "gamma", "sigma"):
        assert word in text


def test_demo_on_the_stage_runs(tmp_path, capsys):
    """`lpvid demo --data stage`: continuous time, D fixed, its files written."""
    out = tmp_path / "stage"
    assert main(["demo", "--data", "stage", "--out", str(out), "--no-figures", "--quiet"]) == 0
    printed = capsys.readouterr().out
    numbers = json.loads((out / "result.json").read_text())
    model = lpvid.LpvModel.load(out / "model.json")
    ds = lpvid.datasets.positioning_stage()
    assert model.Ts is None and not np.any(model.D)
    assert numbers["vnls"] == pytest.approx(lpvid.vnls(model, ds.identification), rel=1e-12)
    assert numbers["validation_vnls"] == pytest.approx(lpvid.vnls(model, ds.validation), rel=1e-12)
    assert f"{numbers['vnls']:.6g}" in printed
    assert not (out / "figures").exists()


def test_fit_suggests_where_to_measure_next(files, tmp_path, capsys):
    out = tmp_path / "out"
    argv = [a.format(f=files, out=out) for a in FIT]
    assert main([*argv, "--suggest", "2", "--no-figures", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "where to measure next" in printed
    data = lpvid.FrfData.load(files / "id.npz")
    points = [float(m) for m in re.findall(r"^  \d\. p = ([-\d.e]+):", printed, re.M)]
    assert len(points) == 2 and len(set(points)) == 2
    lo, hi = data.p_range
    assert all(lo <= p <= hi and not np.any(np.isclose(p, data.p)) for p in points)


def test_fit_resamples_the_spread_and_still_suggests(files, tmp_path, capsys):
    """`--resample 2`: the spread is that of two runs on simulated data; --suggest still works."""
    out = tmp_path / "out"
    argv = [a.format(f=files, out=out) for a in FIT]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", lpvid.ConvergenceWarning)
        code = main([*argv, "--resample", "2", "--suggest", "1", "--no-figures", "--quiet"])
    assert code == 0
    printed = capsys.readouterr().out
    report = (out / "report.md").read_text()
    said = f"{RESAMPLED_SCALE:g} times the median distance of the 2 models identified again"
    assert said in report and "where to measure next" in printed
