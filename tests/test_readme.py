"""The Python examples of README.md and docs/*.md run on the built-in gantry and do as stated."""

from __future__ import annotations

import ast
import contextlib
import doctest
import io
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from frf_files import example_manifest, write_example_files

import lpvid

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"

#: What the tutorial asks a reader to set before running the examples of the
#: pages on the built-in gantry (see "The same steps in Python" in
#: docs/tutorial.md), and the instrument `measure` of "Measured data and
#: simulation" in docs/data.md.
PRELUDE = """
import numpy as np
import lpvid
import lpvid.testing

ds = lpvid.datasets.gantry()
p, freqs_hz, G, sigma, Ts = (
    ds.identification.p, ds.identification.freqs_hz, ds.identification.G,
    ds.identification.sigma, ds.identification.Ts,
)
p_val, G_val, sigma_val = ds.validation.p, ds.validation.G, ds.validation.sigma

_rng = np.random.default_rng(1)
_plant = lpvid.testing.random_lpv(_rng, n=2, r=1, l=1, nb=1, Ts=1e-3)


def measure(u, p):
    # every realisation (row of u) through the plant frozen at p, with output noise
    y = np.stack([_plant.simulate(row, p)[:, 0] for row in u])
    return y + 1e-3 * _rng.normal(size=y.shape)
"""

#: What a page's examples leave in the working directory (the tests look).
WRITES = {
    "README.md": ["model.json"],
    "docs/tutorial.md": ["model.json", "my-report/report.md"],
    "docs/selection.md": ["my-select/select.md"],
    "docs/handoff.md": ["gantry-grid.mat"],
}


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, re.S | re.M)


def code_blocks(text: str) -> list[tuple[str, str]]:
    """The ``python`` and ``{doctest}`` blocks in page order: ``(kind, code)``.

    A doctest block is its examples' source (the doctest builder checks their
    output); the python blocks after it may use what it set.
    """
    out = []
    for kind, body in re.findall(r"^```(python|\{doctest\})\n(.*?)^```", text, re.S | re.M):
        if kind == "python":
            out.append(("python", body))
        else:
            examples = doctest.DocTestParser().get_examples(body)
            out.append(("doctest", "".join(e.source for e in examples)))
    return out


def stated_outputs(block: str) -> list[tuple[str, object]]:
    """``print(EXPR)  # LITERAL`` lines: the expression and the value the comment states."""
    out = []
    for line in block.splitlines():
        m = re.match(r"^print\((.*)\)\s+#\s*(.+)$", line.strip())
        if not m:
            continue
        try:
            value = ast.literal_eval(m.group(2))
        except (ValueError, SyntaxError):
            continue  # a comment in words, not a stated value
        out.append((m.group(1), value))
    return out


def pages() -> list[Path]:
    """The README and every docs page that has Python blocks."""
    docs = sorted(p for p in DOCS.glob("*.md") if python_blocks(p.read_text()))
    return [README, *docs]


PAGES = pages()


def _name(page: Path) -> str:
    return page.relative_to(ROOT).as_posix()


def test_the_pages_have_examples_with_stated_outputs():
    blocks = {_name(p): python_blocks(p.read_text()) for p in PAGES}
    stated = {name: [s for b in bl for s in stated_outputs(b)] for name, bl in blocks.items()}
    # before the README's tutorial moved to docs/ (issue 33): 11 blocks and 9
    # stated outputs in the README, 2 python blocks in docs/getting-started.md
    assert sum(len(b) for b in blocks.values()) >= 14
    assert sum(len(s) for s in stated.values()) >= 14
    assert len(blocks["README.md"]) == 1 and len(stated["README.md"]) >= 3
    assert any("nonzero_groups" in expr for expr, _ in stated["docs/tutorial.md"])
    assert set(WRITES) <= set(blocks)


def write_measured_files(folder: Path, text: str) -> None:
    """The data page's manifest and the files it lists (the gantry's data at its points)."""
    write_example_files(folder, text, lpvid.datasets.gantry().identification)
    (folder / "gantry.toml").write_text(text)


@pytest.fixture(scope="module")
def tutorial_model(tmp_path_factory) -> Path:
    """model.json as the README and the tutorial save it: the gantry identified as the demo does."""
    ds = lpvid.datasets.gantry()
    result = lpvid.identify(ds.identification, ds.order, ds.basis, validation=ds.validation)
    path = tmp_path_factory.mktemp("tutorial") / "model.json"
    result.model.save(path)
    return path


@pytest.mark.parametrize("page", PAGES, ids=_name)
def test_python_examples_run_and_print_what_they_state(page, tmp_path, monkeypatch, request):
    name = _name(page)
    blocks = code_blocks(page.read_text())
    code = "\n".join(body for _, body in blocks)
    if "import control" in code:
        pytest.importorskip("control")  # the hand-off example schedules a gain with it
    # the examples write model.json and report folders into the working
    # directory and read gantry.toml and model.json from it
    monkeypatch.chdir(tmp_path)
    if "gantry.toml" in code:
        pytest.importorskip("pyuff")  # the measured-files example reads UFF
        write_measured_files(tmp_path, example_manifest())
    saves = 'save("model.json")' in code
    if 'load("model.json")' in code or saves:
        model = request.getfixturevalue("tutorial_model")
        if not saves:  # "the gantry model saved in the tutorial"
            shutil.copy(model, tmp_path / "model.json")
    namespace: dict[str, object] = {}
    exec(PRELUDE, namespace)
    for k, (kind, block) in enumerate(blocks):
        with contextlib.redirect_stdout(io.StringIO()):
            exec(compile(block, f"{name} block {k + 1} ({kind})", "exec"), namespace)
        for expr, value in stated_outputs(block):
            got = eval(expr, namespace)
            assert got == value, f"{name} block {k + 1}: {expr} is {got!r}, the page says {value!r}"
    for written in WRITES.get(name, []):
        assert (tmp_path / written).is_file(), f"{name} did not write {written}"
    if saves:  # the model the other pages load is the one this page saves
        saved = lpvid.LpvModel.load(tmp_path / "model.json")
        np.testing.assert_array_equal(saved.theta, lpvid.LpvModel.load(model).theta)


@pytest.mark.parametrize(
    ("block", "expected"),
    [
        ('print(x)  # {"A": [1]}\n', [("x", {"A": [1]})]),
        ("print(x.shape)  # (4000, 2)\n", [("x.shape", (4000, 2))]),
        ("print(x)  # what was chosen and why\n", []),
        ("y = f(x)  # (T, l)\n", []),
    ],
)
def test_stated_outputs_reads_literal_comments_only(block, expected):
    assert stated_outputs(block) == expected


def test_code_blocks_keep_page_order_and_read_doctest_sources():
    text = (
        "```{doctest}\n>>> a = 1\n>>> a + 1\n2\n```\n\n"
        "```python\nb = a + 1\n```\n\n```toml\nc = 3\n```\n"
    )
    assert code_blocks(text) == [("doctest", "a = 1\na + 1\n"), ("python", "b = a + 1\n")]
