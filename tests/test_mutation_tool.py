"""The mutation tool (tools/mutation.py): a mutant's status from its tests in a fresh process."""

from __future__ import annotations

import sys
from pathlib import Path

from tools_loader import load_tool

mutation = load_tool("mutation")

#: A test that does what the mutant's name says (as mutmut's trampoline reads it).
TEST = """
import os, time

def test_the_mutant():
    name = os.environ["MUTANT_UNDER_TEST"]
    if name.endswith("hangs"):
        time.sleep(60)
    assert not name.endswith("killed")
"""


def test_timeouts_are_judged_again_by_the_tests_in_a_fresh_process(tmp_path, monkeypatch):
    """Rejects a mutant called killed (or survived) whatever its tests say, or no timeout kept."""
    tests = tmp_path / "mutants" / "tests"
    tests.mkdir(parents=True)
    (tests / "test_fake.py").write_text(TEST)
    monkeypatch.setattr(mutation, "FRESH_TIMEOUT_S", 5)
    keys = ["lpvid.m.x_f__mutmut_1_killed", "lpvid.m.x_f__mutmut_2_survived", "lpvid.m.x_hangs"]
    statuses = mutation.fresh(tmp_path, Path(sys.executable), ["tests/test_fake.py"], [], keys)
    assert statuses == dict(zip(keys, ["killed", "survived", "timeout"], strict=True))
    # tests that collect nothing say nothing of the mutant (pytest's exit code 5)
    (tests / "test_empty.py").write_text("")
    empty = mutation.fresh(tmp_path, Path(sys.executable), ["tests/test_empty.py"], [], keys[:1])
    assert empty == {keys[0]: "no tests"}


def test_new_statuses_take_the_old_ones_place():
    """Rejects a mutant left under its old status, or one lost or counted twice."""
    results = {"m.py": {"killed": ["a", "b"], "timeout": ["c", "d"], "survived": ["e"]}}
    new = {"c": "survived", "d": "killed"}
    assert mutation.with_statuses(results, new) == {
        "m.py": {"killed": ["a", "b", "d"], "survived": ["c", "e"]}
    }
