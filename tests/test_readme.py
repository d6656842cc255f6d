"""The README's Python examples run, on the built-in gantry, and print what they say."""

from __future__ import annotations

import ast
import contextlib
import io
import re
from pathlib import Path

import numpy as np
import pytest
from frf_files import readme_manifest, write_readme_files

import lpvid

README = Path(__file__).resolve().parents[1] / "README.md"

#: What the README asks a reader to set before running its examples on the
#: built-in gantry (see "The same steps in Python"), and the instrument
#: `measure` of "Measured data and simulation".
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


def python_blocks(text: str) -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", text, re.S | re.M)


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


def test_readme_has_examples_with_stated_outputs():
    blocks = python_blocks(README.read_text())
    assert len(blocks) >= 3
    stated = [s for b in blocks for s in stated_outputs(b)]
    assert any("nonzero_groups" in expr for expr, _ in stated)


def write_measured_files(folder: Path, text: str) -> None:
    """The README's manifest and the files it lists (the gantry's data at its points)."""
    write_readme_files(folder, text, lpvid.datasets.gantry().identification)
    (folder / "gantry.toml").write_text(text)


def test_readme_python_examples_run_and_print_what_they_state(tmp_path, monkeypatch):
    pytest.importorskip("pyuff")  # the measured-files example reads UFF
    pytest.importorskip("control")  # the hand-off example schedules a gain with it
    # the examples write model.json and my-report/ into the working directory
    # and read gantry.toml from it
    monkeypatch.chdir(tmp_path)
    text = README.read_text()
    write_measured_files(tmp_path, readme_manifest())
    namespace: dict[str, object] = {}
    exec(PRELUDE, namespace)
    checked = 0
    for k, block in enumerate(python_blocks(text)):
        with contextlib.redirect_stdout(io.StringIO()):
            exec(compile(block, f"README.md block {k + 1}", "exec"), namespace)
        for expr, value in stated_outputs(block):
            got = eval(expr, namespace)
            assert got == value, (
                f"README block {k + 1}: {expr} is {got!r}, the README says {value!r}"
            )
            checked += 1
    assert checked >= 2
    assert (tmp_path / "model.json").is_file()
    assert (tmp_path / "my-report" / "report.md").is_file()
    assert (tmp_path / "my-select" / "select.md").is_file()
    # the example's result is the demo's: the same data, order and basis
    result = namespace["result"]
    ds = namespace["ds"]
    assert result.data.Ts == ds.identification.Ts
    np.testing.assert_array_equal(result.data.G, ds.identification.G)


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
