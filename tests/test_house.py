"""The house check (tools/house_check.py): import cycles, long files, the README's package map."""

from __future__ import annotations

from pathlib import Path

import pytest
from tools_loader import ROOT, load_tool

house = load_tool("house_check")


def _readme(rows: dict[str, str]) -> str:
    """A README whose package map has one row per folder: ``{folder: may-import cell}``."""
    lines = [
        "# p",
        "",
        "Text.",
        "",
        house.MAP_MARK,
        "| folder | holds | may import |",
        "|---|---|---|",
    ]
    lines += [f"| `{folder}/` | things | {cell} |" for folder, cell in rows.items()]
    return "\n".join([*lines, "", "## Next", "| `other/` | not | `map` |", ""])


def _project(root: Path, files: dict[str, str], readme: str | None = None) -> Path:
    """A project at ``root`` with the package python/lpvid made of ``files``.

    Its README maps every folder with nothing to import unless ``readme`` is given.
    """
    package = root / "python" / "lpvid"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text('"""A synthetic package."""\n')
    for name, text in files.items():
        path = package / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    folders = sorted({name.split("/")[0] for name in files if "/" in name})
    text = _readme({f: "(helpers only)" for f in folders}) if readme is None else readme
    (root / "README.md").write_text(text)
    return root


def _cycles(root: Path) -> list[list[str]]:
    return house.cycles(house.import_graph(root / "python" / "lpvid"))


def test_a_cycle_through_a_type_checking_import_is_found(tmp_path, capsys):
    root = _project(
        tmp_path,
        {
            "model.py": "from lpvid import helper\n",
            "helper.py": (
                "from typing import TYPE_CHECKING\n"
                "if TYPE_CHECKING:\n"
                "    from lpvid.model import Model\n"
            ),
        },
    )
    assert _cycles(root) == [["lpvid.helper", "lpvid.model"]]
    assert house.main([str(root)]) == 1
    out = capsys.readouterr().out
    assert "import cycle: lpvid.helper -> lpvid.model -> lpvid.helper" in out


def test_a_deferred_import_cycle_is_found(tmp_path):
    root = _project(
        tmp_path,
        {
            "fit.py": "def fit():\n    from lpvid.sub.enforce import run\n    return run()\n",
            "sub/__init__.py": "",
            "sub/enforce.py": "import lpvid.sub.refit\n",
            "sub/refit.py": "from lpvid.fit import fit\n",
        },
    )
    assert _cycles(root) == [["lpvid.fit", "lpvid.sub.enforce", "lpvid.sub.refit"]]
    assert house.main([str(root)]) == 1


def test_a_package_init_that_reexports_an_importer_is_a_cycle(tmp_path):
    # fit imports only sub.enforce, but Python runs sub/__init__.py first, which imports fit.
    root = _project(
        tmp_path,
        {
            "fit.py": "from lpvid.sub.enforce import run\n",
            "sub/__init__.py": "from lpvid.sub.refit import refit\n",
            "sub/enforce.py": "def run(): ...\n",
            "sub/refit.py": "from .. import fit\n",
        },
    )
    assert _cycles(root) == [["lpvid.fit", "lpvid.sub", "lpvid.sub.refit"]]


def test_a_clean_package_passes(tmp_path, capsys):
    root = _project(
        tmp_path,
        {
            "model.py": "from lpvid import helper\nfrom lpvid.sub import low\n",
            "helper.py": (
                "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from . import low\n"
            ),
            "low.py": "import numpy\n",
            "sub/__init__.py": "from lpvid.sub.low import x\n",
            "sub/low.py": "from lpvid.sub import other\nx = 1\n",
            "sub/other.py": "",
        },
    )
    (root / "rust").mkdir()
    (root / "rust" / "lib.rs").write_text("fn f() {}\n" * 500)
    assert _cycles(root) == []
    assert house.main([str(root)]) == 0
    assert (
        "house: 0 import cycle(s), 0 file(s) over 500 lines, 0 package map"
        in capsys.readouterr().out
    )


@pytest.mark.parametrize("where", ["python/lpvid/big.py", "rust/big.rs"])
def test_a_file_of_501_lines_is_flagged(tmp_path, capsys, where):
    root = _project(tmp_path, {})
    path = root / where
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("x = 1\n" * 501)
    assert house.long_files(root) == [(Path(where), 501)]
    assert house.main([str(root)]) == 1
    assert f"long file: {where} 501 lines (limit 500)" in capsys.readouterr().out


def test_tests_and_benches_are_not_counted(tmp_path):
    root = _project(tmp_path, {})
    for folder in ("tests", "benches"):
        (root / folder).mkdir()
        (root / folder / "long.py").write_text("x = 1\n" * 600)
    assert house.long_files(root) == []


def test_this_repository_keeps_the_house_rules(capsys):
    assert house.main([str(ROOT)]) == 0, capsys.readouterr().out


def test_the_map_is_read_from_its_table_only():
    text = _readme(
        {"low": "(helpers only)", "mid": "`low/`, `testing`", "top": "`mid/` and `lpvid`"}
    )
    assert house.package_map(text) == {
        "low": set(),
        "mid": {"low", "testing"},
        "top": {"mid", "lpvid"},
    }
    assert house.package_map("# p\n| `a/` | b | `c/` |\n") is None


_LAYERS = {
    "low/__init__.py": "",
    "low/a.py": "from lpvid import _helper, errors\n",
    "mid/__init__.py": "",
    "mid/b.py": "from lpvid.low.a import x\n",
    "top/__init__.py": "",
    "top/c.py": "def f():\n    from lpvid.mid import b\n    import lpvid.testing\n",
    "_helper.py": "",
    "errors.py": "",
    "testing.py": "",
}


def test_imports_the_map_allows_pass(tmp_path, capsys):
    readme = _readme({"low": "(helpers only)", "mid": "`low/`", "top": "`mid/`, `testing`"})
    root = _project(tmp_path, _LAYERS, readme)
    assert house.main([str(root)]) == 0, capsys.readouterr().out


def test_an_import_the_map_does_not_allow_is_named(tmp_path, capsys):
    readme = _readme({"low": "(helpers only)", "mid": "(helpers only)", "top": "`mid/`"})
    root = _project(tmp_path, _LAYERS, readme)
    assert house.main([str(root)]) == 1
    out = capsys.readouterr().out
    assert (
        "package map: lpvid.mid.b imports lpvid.low.a, but the map does not let mid/ import low/"
    ) in out
    # A deferred import counts, and a public top-level module must be listed too.
    assert (
        "package map: lpvid.top.c imports lpvid.testing, "
        "but the map does not let top/ import testing"
    ) in out
    assert "0 import cycle(s), 0 file(s) over 500 lines, 2 package map error(s)" in out


def test_folders_missing_from_the_map_or_absent_are_named(tmp_path, capsys):
    readme = _readme({"low": "(helpers only)", "mid": "`low/`", "gone": "(helpers only)"})
    root = _project(tmp_path, _LAYERS, readme)
    assert house.main([str(root)]) == 1
    out = capsys.readouterr().out
    assert "package map: python/lpvid/top/ has no row in README.md's map" in out
    assert "package map: README.md's map names gone/, which is not a folder of python/lpvid" in out


def test_a_readme_without_a_map_fails(tmp_path, capsys):
    root = _project(tmp_path, {"a.py": ""}, readme="# p\n")
    assert house.main([str(root)]) == 1
    assert "package map: README.md has no map" in capsys.readouterr().out


# ---------------------------------------------------------------- the Rust map

_CRATE = {
    "lib.rs": (
        "pub mod base;\npub mod error;\npub mod eval;\npub mod fit;\n"
        "pub use eval::problem::Problem;\n"
    ),
    "error.rs": "pub struct Error;\n",
    "base/mod.rs": "pub mod layout;\n",
    "base/layout.rs": "use crate::error::Error;\n// crate::fit is only named in a comment\n",
    "eval/mod.rs": "pub mod problem;\n",
    "eval/problem.rs": (
        "use crate::{base::layout, error::Error};\n"
        'const S: &str = "crate::fit::lm";\n'
        "#[cfg(test)]\nmod tests {\n    fn f() { let _ = crate::base::layout::X; }\n}\n"
    ),
    "fit/mod.rs": "use crate::Problem;\npub fn f() { crate::base::layout::g(); }\n",
}


def _rust_readme(rows: dict[str, str]) -> str:
    """A README mapping the Python folder ``sub/``, and a Rust map ``{folder: may-use cell}``."""
    lines = [
        _readme({"sub": "(helpers only)"}),
        house.RUST_MAP_MARK,
        "| folder | what it holds | may use |",
        "|---|---|---|",
    ]
    lines += [f"| `{folder}/` | things | {cell} |" for folder, cell in rows.items()]
    return "\n".join([*lines, ""])


def _crate(root: Path, files: dict[str, str], rows: dict[str, str]) -> Path:
    """A project of one Python folder, the crate ``files`` in rust/ and a Rust map of ``rows``."""
    _project(root, {"sub/__init__.py": ""}, _rust_readme(rows))
    for name, text in files.items():
        path = root / "rust" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_the_crate_paths_are_read_outside_comments_and_strings():
    source = (
        "use crate::{a::{b, c}, d};\n// crate::comment\n/* crate::block */\n"
        'let s = "crate::string"; let q = \'"\'; crate::e::f(); x = crate :: g;\n'
    )
    assert house.rust_uses(source) == {"a", "d", "e", "g"}


def test_a_crate_whose_uses_the_map_allows_passes(tmp_path, capsys):
    rows = {"base": "(errors only)", "eval": "`base/`", "fit": "`eval/`, `base/`"}
    root = _crate(tmp_path, _CRATE, rows)
    # fit/ uses crate::Problem, a re-export of eval/.
    assert house.rust_use_graph(root / "rust")["fit/mod.rs"] == {"eval", "base"}
    assert house.main([str(root)]) == 0, capsys.readouterr().out
    assert "0 Rust map error(s)" in capsys.readouterr().out


def test_a_missing_folder_row_and_an_unlisted_use_fail(tmp_path, capsys):
    rows = {"base": "(errors only)", "fit": "`base/`", "gone": "(errors only)"}
    root = _crate(tmp_path, _CRATE, rows)
    assert house.main([str(root)]) == 1
    out = capsys.readouterr().out
    assert "rust map: rust/eval/ has no row in README.md's Rust map" in out
    assert "rust map: README.md's Rust map names gone/, which is not a folder of rust" in out
    assert (
        "rust map: rust/fit/mod.rs uses crate::eval, but the map does not let fit/ use eval/"
    ) in out
    assert "3 Rust map error(s)" in out


def test_folders_that_use_each_other_in_a_circle_fail(tmp_path, capsys):
    files = {**_CRATE, "base/layout.rs": "use crate::fit::f;\n"}
    rows = {"base": "`fit/`", "eval": "`base/`", "fit": "`eval/`, `base/`"}
    root = _crate(tmp_path, files, rows)
    assert house.main([str(root)]) == 1
    assert "rust map: folders in a circle: base -> fit -> base" in capsys.readouterr().out


def test_a_crate_with_folders_needs_a_rust_map(tmp_path, capsys):
    root = _crate(tmp_path, _CRATE, {})
    (root / "README.md").write_text(_readme({"sub": "(helpers only)"}))
    assert house.main([str(root)]) == 1
    assert "rust map: README.md has no Rust map" in capsys.readouterr().out
