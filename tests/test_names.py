"""Cited names resolve and cited source files exist; exports are public.

Dotted names from the docstrings, README and docs/*.md; source files from
the README and docs/*.md.
"""

import ast
import importlib
import re
from pathlib import Path

import pytest

import lpvid
from lpvid import _core

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "python" / "lpvid"
DOTTED = re.compile(r"(?<![\w./-])lpvid(?:\.[A-Za-z_]\w*)+")
#: The pages: the README and every page of docs/.
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _docstrings(path: Path) -> list[str]:
    tree = ast.parse(path.read_text())
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef):
            doc = ast.get_docstring(node)
            if doc:
                out.append(doc)
    return out


def _cited() -> dict[str, str]:
    names: dict[str, str] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        for doc in _docstrings(path):
            for name in DOTTED.findall(doc):
                names.setdefault(name, str(path.relative_to(ROOT)))
    for page in PAGES:
        for name in DOTTED.findall(page.read_text()):
            names.setdefault(name, page.relative_to(ROOT).as_posix())
    return names


def resolve(name: str) -> object:
    """Import the longest module prefix of ``name`` and look up the rest as attributes."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj: object = importlib.import_module(".".join(parts[:k]))
        except ModuleNotFoundError:
            continue
        for attr in parts[k:]:
            obj = getattr(obj, attr)
        return obj
    raise ModuleNotFoundError(name)


CITED = _cited()

#: A source file of this repository as the pages cite it (`rust/socp/warm.rs`).
SOURCE = re.compile(
    r"(?<![\w./-])(?:rust|python/lpvid|benches|tests|tools)/[\w./-]*\w\.(?:rs|py|toml)"
)


def _cited_sources() -> dict[str, str]:
    # The changelog is history: it keeps the paths of its day.
    out: dict[str, str] = {}
    for page in PAGES:
        if page.name != "changelog.md":
            for path in SOURCE.findall(page.read_text()):
                out.setdefault(path, page.relative_to(ROOT).as_posix())
    return out


CITED_SOURCES = _cited_sources()


def test_the_walk_finds_names():
    # The walk itself: it must see the names the package is built around.
    assert {"lpvid.fit_l21", "lpvid.initial.interpolation.FORMS", "lpvid.datasets.gantry"} <= set(
        CITED
    )


def test_every_source_file_the_pages_cite_exists():
    # The walk sees the files the method is described by, and every one
    # cited is in the tree (a file replaced must take its descriptions along).
    assert {"rust/socp/warm.rs", "rust/l21/mod.rs", "benches/bench_scale.py"} <= set(CITED_SOURCES)
    missing = [
        f"{path} (cited in {page})"
        for path, page in CITED_SOURCES.items()
        if not (ROOT / path).exists()
    ]
    assert not missing, "cited files not in the tree: " + "; ".join(missing)


@pytest.mark.parametrize("name", sorted(CITED))
def test_cited_name_resolves(name):
    try:
        resolve(name)
    except (AttributeError, ModuleNotFoundError) as exc:
        pytest.fail(f"{name} (cited in {CITED[name]}) does not resolve: {exc}")


def test_module_names_are_not_shadowed():
    # A function re-exported under a module's name hides the module (the old
    # lpvid.smile.FORMS bug): every submodule stays reachable as a module.
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        parts = [p for p in rel.parts if p != "__init__"]
        if any(p.startswith("_") for p in parts[1:]):
            continue
        dotted = ".".join(parts)
        module = importlib.import_module(dotted)
        parent, _, last = dotted.rpartition(".")
        if parent:
            seen = getattr(importlib.import_module(parent), last)
            assert seen is module, f"{parent}.{last} is {seen!r}, not the module {dotted}"


def test_public_names_are_exported():
    for name in lpvid.__all__:
        assert hasattr(lpvid, name), name
    assert "_core" not in lpvid.__all__
    assert lpvid.SingularModelError is _core.SingularModelError


def test_l21_settings_mirror_the_core():
    core = _core.l21_defaults()
    mine = lpvid.L21Settings().to_core(gamma=core["gamma"])
    assert mine == core
