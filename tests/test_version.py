"""The version comes from one place, Cargo.toml."""

import re
from importlib.metadata import version
from pathlib import Path

import lpvid


def cargo_version() -> str:
    text = (Path(__file__).resolve().parents[1] / "Cargo.toml").read_text()
    package = text.split("[package]", 1)[1].split("\n[", 1)[0]
    found = re.search(r'^version\s*=\s*"([^"]+)"', package, re.MULTILINE)
    assert found is not None, "no version in Cargo.toml's [package]"
    return found.group(1)


def test_version_is_cargo_tomls():
    assert lpvid.__version__ == cargo_version()
    # The installed metadata (pyproject's dynamic version) agrees.
    assert version("lpvid") == cargo_version()
