#!/usr/bin/env python3
"""Mutation testing of lpvid: which wrong code do the tests let through? (not run by CI).

Python (mutmut 3.8.1, ``pip install mutmut==3.8.1`` into the venv that has lpvid built)::

    python tools/mutation.py py stable/scan.py                   # the module's fast tests
    python tools/mutation.py py selection/result.py --tests tests/test_select.py  # tests you choose
    python tools/mutation.py py trust/                          # every module of a folder

Rust (cargo-mutants, ``cargo install cargo-mutants``)::

    python tools/mutation.py rust rust/fit/lm.rs                # its fast cargo tests
    python tools/mutation.py rust rust/fit/lm.rs -- --test core_optimisers

Each run prints the killed / total per module and the survivors (``--show``:
with their diffs). Python modules are copied with their tests to a staging
directory (mutmut names mutants after the path and strips only ``src/``, so
``python/lpvid`` becomes ``src/lpvid`` there), the built ``_core`` included;
``--stage DIR`` keeps it, and ``--stage DIR --recheck`` runs only its
survivors again against the current tests (after writing tests for them).
A mutant mutmut calls a timeout is run again with its tests in a fresh
process (mutmut's forked workers can hang starting a thread), and the
tests' verdict stands.
Rust mutants are built and tested by cargo-mutants in its own copy of the
tree with the test profile (opt-level 1, the dependencies optimised, no
debug information): the first build there compiles the dependencies (about
8 minutes on two cores), then each mutant takes a few seconds of
building. Runs are long on two cores: one module at a time, under
``nice``.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: The fast test files that exercise each Python module (relative to python/lpvid).
PY_TESTS = {
    "trust/uncertainty.py": [
        "tests/test_covariance.py",
        "tests/test_nextpoints.py",
        "tests/test_covariance_parts.py",
    ],
    "experiment/design.py": ["tests/test_nextpoints.py", "tests/test_design.py"],
    "experiment/nextpoints.py": ["tests/test_nextpoints.py", "tests/test_nextpoints_parts.py"],
    "stable/enforce.py": ["tests/test_stable_fit.py", "tests/test_enforce.py"],
    "stable/lyapunov.py": ["tests/test_stability.py", "tests/test_lyapunov.py"],
    "stable/ranges.py": [
        "tests/test_stability.py",
        "tests/test_stable_fit.py",
        "tests/test_ranges.py",
    ],
    "trust/support.py": ["tests/test_stable_fit.py", "tests/test_pipeline.py"],
    "stable/scan.py": [
        "tests/test_stability.py",
        "tests/test_stable_fit.py",
        "tests/test_stability_parts.py",
    ],
    "trust/steps.py": ["tests/test_stable_fit.py", "tests/test_steps.py"],
    "trust/__init__.py": ["tests/test_stability.py"],
    "selection/grid.py": ["tests/test_select_rules.py", "tests/test_select_parts.py"],
    "selection/result.py": ["tests/test_select_rules.py"],
    "fit/timefit.py": ["tests/test_timefit.py"],
    "fit/timecost.py": ["tests/test_timefit.py", "tests/test_timedata.py"],
    "readers/": [
        "tests/test_readers.py",
        "tests/test_reader_errors.py",
        "tests/test_mixed_files.py",
        "tests/test_files.py",
        "tests/test_matlab.py",
        "tests/test_table.py",
        "tests/test_uff.py",
        "tests/test_reader_parts.py",
        "tests/test_manifest.py",
    ],
}

#: The cargo test targets that exercise each Rust file (fast ones first).
RUST_TESTS = {
    "rust/fit/lm.rs": ["--test", "core_optimisers", "--lib"],
    "rust/fit/mod.rs": ["--test", "core_optimisers", "--lib"],
    "rust/l21/mod.rs": ["--test", "core_optimisers", "--lib"],
    "rust/socp/": ["--test", "core_optimisers", "--lib"],
}

STATUS = {1: "killed", 3: "killed", 0: "survived", 5: "no tests", 33: "no tests", 34: "skipped"}
STATUS.update({36: "timeout", -24: "timeout", 24: "timeout", 152: "timeout", 255: "timeout"})
STATUS.update({None: "not checked", 37: "caught by type check", -11: "segfault", -9: "segfault"})


#: Every mutant's status after the last run or re-check, kept in the staging directory.
STATUS_FILE = "lpvid-mutants.json"


def _tests_for(module: str) -> list[str]:
    for key in (module, module.rsplit("/", 1)[0] + "/" if "/" in module else ""):
        if key in PY_TESTS:
            return PY_TESTS[key]
    raise SystemExit(f"module: no fast tests known for {module}; name the test files after it")


def _stage(stage: Path, modules: list[str], tests: list[str], pytest_args: list[str]) -> None:
    """The package as src/lpvid (with the built core), the tests and a mutmut configuration."""
    src = stage / "src" / "lpvid"
    if src.exists():
        shutil.rmtree(src)
    src.parent.mkdir(parents=True, exist_ok=True)
    shutil.copytree(ROOT / "python" / "lpvid", src, ignore=shutil.ignore_patterns("__pycache__"))
    if not list(src.glob("_core*.so")) and not list(src.glob("_core*.pyd")):
        raise SystemExit("lpvid._core is not built: pip install -e '.[test]' first")
    if (stage / "tests").exists():
        shutil.rmtree(stage / "tests")
    shutil.copytree(ROOT / "tests", stage / "tests", ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pyproject.toml", "README.md"):  # tests read the README's examples
        shutil.copy(ROOT / name, stage / name)
    if (stage / "docs").exists():
        shutil.rmtree(stage / "docs")
    (stage / "docs").mkdir()
    for page in (ROOT / "docs").glob("*.md"):  # and those of the docs pages
        shutil.copy(page, stage / "docs" / page.name)
    lines = [
        "[mutmut]",
        "source_paths = src/lpvid",
        "also_copy =",
        "    README.md",
        "    docs",
        "only_mutate =",
    ]
    lines += [f"    src/lpvid/{m}{'*' if m.endswith('/') else ''}" for m in modules]
    lines += ["pytest_add_cli_args_test_selection ="] + [f"    {t}" for t in tests]
    lines += ["pytest_add_cli_args =", "    -p", "    no:cacheprovider"]
    lines += [f"    {a}" for a in pytest_args]
    lines += ["process_isolation = forkserver", ""]
    (stage / "setup.cfg").write_text("\n".join(lines))


def py_results(stage: Path) -> dict[str, dict[str, list[str]]]:
    """Mutant names by status, per mutated file, from mutmut's meta files."""
    out: dict[str, dict[str, list[str]]] = {}
    for meta in sorted((stage / "mutants").rglob("*.py.meta")):
        codes = json.loads(meta.read_text())["exit_code_by_key"]
        name = str(meta.relative_to(stage / "mutants" / "src" / "lpvid"))[: -len(".meta")]
        by: dict[str, list[str]] = {}
        for key, code in sorted(codes.items()):
            by.setdefault(STATUS.get(code, "suspicious"), []).append(key)
        if codes:
            out[name] = by
    return out


def merged(
    before: dict[str, dict[str, list[str]]], after: dict[str, dict[str, list[str]]]
) -> dict[str, dict[str, list[str]]]:
    """The whole module after a re-check: the mutants not run again keep their first status.

    mutmut marks the mutants a re-check did not run as not checked; their
    status from the first run still holds (the re-check only adds tests).
    """
    out: dict[str, dict[str, list[str]]] = {}
    for name in sorted(set(before) | set(after)):
        status = {k: s for s, keys in before.get(name, {}).items() for k in keys}
        for s, keys in after.get(name, {}).items():
            for k in keys:
                if s != "not checked" or k not in status:
                    status[k] = s
        out[name] = _grouped(status)
    return out


def _grouped(status: dict[str, str]) -> dict[str, list[str]]:
    """Mutant names by status, each list sorted, from every mutant's status."""
    by: dict[str, list[str]] = {}
    for k, s in sorted(status.items()):
        by.setdefault(s, []).append(k)
    return by


#: Seconds a mutant's tests may take when run again in a fresh process.
FRESH_TIMEOUT_S = 600


def fresh(
    stage: Path, py: Path, tests: list[str], pytest_args: list[str], keys: list[str]
) -> dict[str, str]:
    """The status of each mutant with its tests run in a fresh process of its own.

    mutmut runs the tests in workers forked from a process that has run
    lpvid, and such a worker can hang for good starting a thread (seen on
    ``_spread.py``'s tests, which start thread pools: the worker waits in
    ``Thread.start`` for a thread that never signals it runs): mutmut then
    calls the mutant a timeout, which would count as killed, whatever the
    tests say of it. Here the tests decide:
    ``killed`` when they fail, ``survived`` when they pass (``no tests``
    when none ran, as mutmut reads pytest's exit codes), ``timeout`` only
    after :data:`FRESH_TIMEOUT_S`.
    """
    out = {}
    env = dict(os.environ, PYTHONPATH=str(stage / "mutants" / "src"))
    cmd = [str(py), "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *tests, *pytest_args]
    for key in keys:
        env["MUTANT_UNDER_TEST"] = key
        try:
            run = subprocess.run(
                ["nice", "-n", "19", *cmd],
                cwd=stage / "mutants",
                env=env,
                capture_output=True,
                timeout=FRESH_TIMEOUT_S,
            )
            out[key] = STATUS.get(run.returncode, "suspicious")  # pytest's codes are mutmut's
        except subprocess.TimeoutExpired:
            out[key] = "timeout"
        print(f"  {key}: {out[key]} (run again in a fresh process)", flush=True)
    return out


def with_statuses(
    results: dict[str, dict[str, list[str]]], new: dict[str, str]
) -> dict[str, dict[str, list[str]]]:
    """``results`` with the statuses of ``new`` put in place of the mutants' old ones."""
    return {
        name: _grouped({k: new.get(k, s) for s, keys in by.items() for k in keys})
        for name, by in results.items()
    }


def _rate(by: dict[str, list[str]]) -> str:
    total = sum(len(v) for v in by.values())
    killed = len(by.get("killed", [])) + len(by.get("timeout", []))
    return f"{killed}/{total} killed ({100.0 * killed / max(total, 1):.1f} %)"


def run_python(args: argparse.Namespace) -> int:
    """Mutmut on the modules in a staging directory; prints the rates and the survivors."""
    modules = [m.removeprefix("python/lpvid/") for m in args.modules]
    tests = args.tests or sorted({t for m in modules for t in _tests_for(m)})
    py = Path(args.python or (ROOT / ".venv" / "bin" / "python"))
    mutmut = py.parent / "mutmut"
    if not mutmut.exists():
        raise SystemExit(f"mutmut not found next to {py}: pip install mutmut==3.8.1")
    stage = Path(args.stage) if args.stage else Path(tempfile.mkdtemp(prefix="lpvid-mutmut."))
    stage.mkdir(parents=True, exist_ok=True)
    again: list[str] = []
    before: dict[str, dict[str, list[str]]] = {}
    if args.recheck:
        saved = stage / STATUS_FILE
        before = json.loads(saved.read_text()) if saved.exists() else py_results(stage)
        again = [k for by in before.values() for k in by.get("survived", [])]
        if not before:
            raise SystemExit(f"--recheck: no results in {stage} to re-check")
    _stage(stage, modules, tests, shlex.split(args.pytest_args))
    print(f"mutating {', '.join(modules)} against {' '.join(tests)} in {stage}", flush=True)
    cmd = ["nice", "-n", "19", str(mutmut), "run", "--max-children", str(args.jobs)]
    if args.recheck:
        print(f"re-checking the {len(again)} survivors with the current tests", flush=True)
        cmd += again
    code = subprocess.run(cmd, cwd=stage).returncode if again or not args.recheck else 0
    results = merged(before, py_results(stage)) if args.recheck else py_results(stage)
    hung = [k for by in results.values() for k in by.get("timeout", [])]
    if hung:
        print(f"running the {len(hung)} timeouts again, each in a fresh process", flush=True)
        extra = shlex.split(args.pytest_args)
        results = with_statuses(results, fresh(stage, py, tests, extra, hung))
    (stage / STATUS_FILE).write_text(json.dumps(results, indent=1))
    print()
    for name, by in results.items():
        print(f"{name}: {_rate(by)}")
        for status, keys in by.items():
            if status in ("killed", "timeout"):
                continue
            for key in keys:
                print(f"  {status}: {key}")
                if args.show:
                    shown = subprocess.run(
                        [str(mutmut), "show", key], cwd=stage, capture_output=True, text=True
                    )
                    print("    " + shown.stdout.strip().replace("\n", "\n    "))
    print(f"staging dir: {stage} (mutmut show NAME there; --stage {stage} to run again)")
    return code if not results else 0


def rust_results(out: Path) -> dict[str, list[str]]:
    """cargo-mutants' outcomes by kind: caught, missed, timeout, unviable."""
    found = {}
    for kind in ("caught", "missed", "timeout", "unviable"):
        f = out / "mutants.out" / f"{kind}.txt"
        found[kind] = [x for x in f.read_text().splitlines() if x] if f.exists() else []
    return found


def run_rust(args: argparse.Namespace) -> int:
    """cargo-mutants on the files; prints the rate and the mutants missed."""
    if shutil.which("cargo-mutants") is None:
        raise SystemExit("cargo-mutants not found: cargo install cargo-mutants")
    files = args.files
    extra = args.cargo_args or next(
        (v for k, v in RUST_TESTS.items() if all(f.startswith(k) for f in files)), []
    )
    out = Path(args.stage) if args.stage else Path(tempfile.mkdtemp(prefix="lpvid-mutants."))
    cmd = ["nice", "-n", "19", "cargo", "mutants", "--no-shuffle", "-j", str(args.jobs)]
    cmd += ["--output", str(out)]
    for f in files:
        cmd += ["--file", f]
    cmd += ["--", *extra]
    print(" ".join(cmd), flush=True)
    # Without debug information: the baseline build (dependencies included)
    # 22 -> 8 minutes on two cores, each mutant's build 25 s -> 2-10 s.
    env = dict(
        os.environ,
        CARGO_TERM_COLOR="never",
        CARGO_PROFILE_DEV_DEBUG="0",
        CARGO_PROFILE_TEST_DEBUG="0",
    )
    code = subprocess.run(cmd, cwd=ROOT, env=env).returncode
    found = rust_results(out)
    viable = len(found["caught"]) + len(found["missed"]) + len(found["timeout"])
    killed = len(found["caught"]) + len(found["timeout"])
    rate = 100.0 * killed / max(viable, 1)
    print(f"\n{' '.join(files)}: {killed}/{viable} killed ({rate:.1f} %),")
    print(f"  {len(found['unviable'])} unviable (do not compile), {len(found['timeout'])} timeouts")
    for m in found["missed"]:
        print(f"  missed: {m}")
    print(f"outcomes: {out / 'mutants.out'}")
    return 0 if viable else code


def main(argv: list[str] | None = None) -> int:
    """The command line (module notes)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="lang", required=True)
    p = sub.add_parser("py", help="mutmut on Python modules of lpvid")
    p.add_argument("modules", nargs="+", help="e.g. stable/scan.py or readers/")
    p.add_argument("--tests", nargs="+", help="test files (default: the module's fast ones)")
    p.add_argument("--stage", help="staging directory (kept; default: a new temporary one)")
    p.add_argument("--python", help="the venv's python (default .venv/bin/python)")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument(
        "--pytest-args",
        default="",
        help="more pytest arguments for every run, e.g. --pytest-args=\"-k 'not grid'\"",
    )
    p.add_argument("--show", action="store_true", help="print the diff of every survivor")
    p.add_argument(
        "--recheck",
        action="store_true",
        help="with --stage: run only the survivors again, against the current tests",
    )
    r = sub.add_parser("rust", help="cargo-mutants on Rust files of the core")
    r.add_argument("files", nargs="+", help="e.g. rust/fit/lm.rs rust/socp/mod.rs")
    r.add_argument("--stage", help="output directory of cargo-mutants")
    r.add_argument("--jobs", type=int, default=1)
    parser.epilog = "rust: arguments after -- go to cargo test (default: the file's fast tests)"
    argv = sys.argv[1:] if argv is None else argv
    cut = argv.index("--") if "--" in argv else len(argv)
    args = parser.parse_args(argv[:cut])
    args.cargo_args = argv[cut + 1 :]
    if args.cargo_args and args.lang != "rust":
        parser.error("arguments after -- are cargo test arguments (rust only)")
    return run_python(args) if args.lang == "py" else run_rust(args)


if __name__ == "__main__":
    sys.exit(main())
