"""A report folder is complete or not there: written beside, then put in place whole.

Ctrl-C (or an error) while ``lpvid demo``/``lpvid fit`` writes its results
used to leave a folder with a model file but no report. Here the writing is
interrupted at several places (monkeypatched to raise KeyboardInterrupt) and
the folder checked: absent when it was new, byte for byte the old one when
it replaced an earlier report, and no temporary folder left beside it.
"""

import threading
from pathlib import Path

import numpy as np
import pytest

import lpvid
import lpvid._files
import lpvid.report.figures
import lpvid.report.markdown
import lpvid.testing
from lpvid.cli import main


@pytest.fixture(scope="module")
def result():
    ds = lpvid.datasets.gantry(n_lines=40)
    return lpvid.identify(ds.identification, ds.order, ds.basis, validation=ds.validation)


@pytest.fixture(autouse=True)
def quick(monkeypatch):
    """The report's stability section (a second of root finding and an LMI) left out."""
    monkeypatch.setattr(lpvid.report.markdown, "_trust", lambda result: [])


def snapshot(folder):
    """Every file under ``folder`` with its bytes."""
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def leftovers(parent, name):
    """Temporary folders of ``name`` left in ``parent``."""
    return sorted(p.name for p in parent.iterdir() if p.name.startswith(f".{name}."))


def interrupt(*args, **kwargs):
    raise KeyboardInterrupt


def interrupted_at(name):
    """``write_atomic`` of the report module, interrupted at the file ``name``."""
    real = lpvid.report.markdown.write_atomic

    def write(path, fill):
        if path.name == name:
            raise KeyboardInterrupt
        return real(path, fill)

    return write


@pytest.mark.parametrize("where", ["key_numbers", "_markdown", "write_atomic"])
def test_an_interrupted_report_leaves_no_folder(result, tmp_path, monkeypatch, where):
    out = tmp_path / "report"
    if where == "write_atomic":
        # The last file (report.md) fails after the model files are written.
        monkeypatch.setattr(lpvid.report.markdown, "write_atomic", interrupted_at("report.md"))
    else:
        monkeypatch.setattr(lpvid.report.markdown, where, interrupt)
    with pytest.raises(KeyboardInterrupt):
        lpvid.report.markdown.write_report(result, out, figures=False)
    assert not out.exists()
    assert leftovers(tmp_path, "report") == []


def test_an_interrupted_rewrite_leaves_the_old_report_untouched(result, tmp_path, monkeypatch):
    out = tmp_path / "report"
    lpvid.report.markdown.write_report(result, out, title="first", figures=False)
    before = snapshot(out)
    assert {str(p) for p in before} == {"report.md", "model.json", "model.mat", "result.json"}
    monkeypatch.setattr(lpvid.report.markdown, "_markdown", interrupt)
    with pytest.raises(KeyboardInterrupt):
        lpvid.report.markdown.write_report(result, out, title="second", figures=False)
    assert snapshot(out) == before
    assert leftovers(tmp_path, "report") == []


@pytest.mark.parametrize("exchange", [True, False])
def test_a_complete_rewrite_replaces_the_old_folder_whole(result, tmp_path, monkeypatch, exchange):
    out = tmp_path / "report"
    lpvid.report.markdown.write_report(result, out, title="first", figures=False)
    (out / "grid.json").write_text("{}")  # from an earlier lpvid select
    if not exchange:  # the two-rename path of systems without renameat2
        monkeypatch.setattr(lpvid._files, "_exchange", lambda a, b: False)
    path = lpvid.report.markdown.write_report(result, out, title="second", figures=False)
    assert path == out / "report.md"
    assert path.read_text().startswith("# second")
    assert not (out / "grid.json").exists()
    assert lpvid.LpvModel.load(out / "model.json").theta.tolist() == result.model.theta.tolist()
    assert leftovers(tmp_path, "report") == []


def test_a_folder_with_other_files_is_not_replaced(result, tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "measurements.npz").write_bytes(b"precious")
    with pytest.raises(FileExistsError, match=r"measurements\.npz"):
        lpvid.report.markdown.write_report(result, out, figures=False)
    assert snapshot(out) == {Path("measurements.npz"): b"precious"}
    assert leftovers(tmp_path, "mine") == []


def test_an_interrupted_figure_leaves_no_folder(result, tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    out = tmp_path / "report"
    real, drawn = lpvid.report.figures.draw, []

    def second_fails(job, folder):
        if drawn:
            raise KeyboardInterrupt
        drawn.append(real(job, folder))
        return drawn[-1]

    monkeypatch.setattr(lpvid.report.figures, "draw", second_fails)
    with pytest.raises(KeyboardInterrupt):
        lpvid.report.markdown.write_report(result, out)
    assert drawn and drawn[0].suffix == ".png"  # a figure was written before the interrupt
    assert not out.exists()
    assert leftovers(tmp_path, "report") == []


def test_ctrl_c_while_the_demo_writes_exits_130_and_keeps_the_old_report(
    result, tmp_path, monkeypatch, capsys
):
    out = tmp_path / "demo"
    monkeypatch.setattr(lpvid, "identify", lambda *args, **kwargs: result)
    assert main(["demo", "--out", str(out), "--no-figures", "--quiet"]) == 0
    before = snapshot(out)
    monkeypatch.setattr(lpvid.report.markdown, "_markdown", interrupt)
    assert main(["demo", "--out", str(out), "--no-figures", "--quiet"]) == 130
    assert capsys.readouterr().err.strip().endswith("lpvid demo: interrupted")
    assert snapshot(out) == before
    assert leftovers(tmp_path, "demo") == []


def test_the_cli_refuses_an_out_folder_with_other_files_before_computing(tmp_path, capsys):
    out = tmp_path / "data"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert main(["demo", "--out", str(out), "--no-figures", "--quiet"]) == 2
    err = capsys.readouterr()
    assert "--out" in err.err and "notes.txt" in err.err
    assert "local models" not in err.out
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


def test_select_report_is_written_whole(tmp_path, monkeypatch):
    rng = np.random.default_rng(0)
    true = lpvid.testing.modal_lpv([[10.0, 3.0]])
    f = np.linspace(2, 30, 30)
    data = lpvid.testing.noisy_data(true, [0.0, 0.5, 1.0], f, rng, 0.01)
    val = lpvid.testing.noisy_data(true, [0.25, 0.75], f, rng, 0.01)
    sel = lpvid.select(data, [2], [1], validation=val)
    out = tmp_path / "sel"
    real = lpvid.report.markdown.write_atomic
    monkeypatch.setattr(lpvid.report.markdown, "write_atomic", interrupted_at("select.md"))
    with pytest.raises(KeyboardInterrupt):
        lpvid.report.markdown.write_select_report(sel, out, figures=False)
    assert not out.exists() and leftovers(tmp_path, "sel") == []
    monkeypatch.setattr(lpvid.report.markdown, "write_atomic", real)
    path = lpvid.report.markdown.write_select_report(sel, out, figures=False)
    assert path == out / "select.md" and path.exists() and (out / "report.md").exists()


def test_figures_still_drawing_finish_before_the_folder_is_removed(result, tmp_path, monkeypatch):
    """Ctrl-C while a pool draws: the jobs running are waited for, so none writes afterwards."""
    from concurrent.futures import ThreadPoolExecutor

    started = threading.Event()
    written = []

    def slow(job, folder):
        started.set()
        threading.Event().wait(0.3)
        # The worst a job can do: make the folder again and write into it.
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / job.name
        path.write_bytes(b"png")
        written.append(path)
        return path

    def interrupt_once_drawing(*args, **kwargs):
        started.wait(10)
        raise KeyboardInterrupt

    monkeypatch.setattr(lpvid.report.figures, "draw", slow)
    monkeypatch.setattr(lpvid.report.markdown, "_trust", interrupt_once_drawing)
    out = tmp_path / "report"
    with ThreadPoolExecutor(2) as pool, pytest.raises(KeyboardInterrupt):
        lpvid.report.markdown.write_report(result, out, pool=pool)
    assert written  # a job was running when Ctrl-C came, and finished
    assert not out.exists()
    assert leftovers(tmp_path, "report") == []


def test_the_current_folder_is_never_replaced(result, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # empty: nothing else would stop it
    with pytest.raises(FileExistsError, match="current folder"):
        lpvid.report.markdown.write_report(result, ".", figures=False)
    assert list(tmp_path.iterdir()) == []
