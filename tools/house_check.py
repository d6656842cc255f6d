#!/usr/bin/env python3
"""The house check of lpvid: no import cycle, no long source file, true maps of the folders.

Usage::

    python3 tools/house_check.py [PROJECT_ROOT]    (default: the current directory)

Four rules, all about how the code is laid out rather than what it does:

- **No import cycle** among the modules of ``python/lpvid``. Every import
  counts: at module level, inside a function (a deferred import), and under
  ``if TYPE_CHECKING:`` (an import made only for a type hint is still a tie
  between two modules). A package's ``__init__.py`` is a module like any
  other: ``from lpvid.initial import x`` ties the importer to
  ``lpvid/initial/__init__.py``, and so does ``from lpvid.initial.interpolation
  import x`` (besides ``lpvid.initial.interpolation``) when the importer is not in
  ``lpvid.initial`` itself, because Python runs the package's
  ``__init__.py`` first. Inside a package its own ``__init__.py`` is not
  counted (or every package that re-exports its modules would be a cycle);
  nor is the top package's, which every module lies in. A compiled module
  is known by its type stub (``_core.pyi``).
- **No source file over 500 lines**: ``python/lpvid/**/*.py`` and
  ``rust/**/*.rs`` (tests and benches are not counted).
- **The README's package map is true**: the table below the line
  :data:`MAP_MARK` in ``README.md`` has one row per folder of
  ``python/lpvid`` (none missing, none that is not there), and its last
  column names what the folder's modules may import: every import from a
  module of one folder into another folder (or into a public top-level
  module such as ``lpvid.testing``, or ``lpvid`` itself) must be listed
  there. The private top-level modules (``lpvid._*``) and ``lpvid.errors``
  may be imported from anywhere.
- **The README's Rust map is true**: the table below the line
  :data:`RUST_MAP_MARK` has one row per folder of ``rust/`` (a top-level
  module of the crate; its subfolders belong to it), and its last column
  names the other folders its files may ``use``: every path ``crate::x``
  in a file of one folder (outside comments and strings; ``use`` lines,
  paths in code and the files' tests alike) that leads into another folder
  must be listed there, and the folders may not use each other in a circle.
  A name the crate root re-exports (``crate::Problem``) counts as the
  folder it comes from; the modules at the root of ``rust/`` named in
  :data:`RUST_FREE` (the errors, the test helpers) may be used from
  anywhere. Checked when ``rust/`` has folders.

Prints every cycle (the modules of one strongly connected component of the
import graph, with one closed path through them) and every long file, then a
summary line. Exit status 0 when there are none, 1 otherwise.

Uses only the standard library, so that it runs before anything is installed.
"""

from __future__ import annotations

import ast
import re
import sys
from collections.abc import Iterable, Mapping
from pathlib import Path

__all__ = [
    "LIMIT",
    "cycles",
    "import_graph",
    "imports_of",
    "long_files",
    "main",
    "map_breaks",
    "package_map",
    "module_names",
    "one_cycle",
    "rust_folders",
    "rust_map_breaks",
    "rust_uses",
    "rust_use_graph",
]

#: Most lines a source file may have.
LIMIT = 500

#: The line of README.md right above the package map's table.
MAP_MARK = "<!-- package map: tools/house_check.py keeps it true -->"

#: Top-level modules every folder may import without listing them.
FREE = re.compile(r"^lpvid\.(_[A-Za-z0-9_]*|errors)$")

#: The line of README.md right above the Rust map's table.
RUST_MAP_MARK = "<!-- rust map: tools/house_check.py keeps it true -->"

#: Modules at the root of rust/ that every folder may use without listing
#: them: the typed errors and the test helpers (used by tests only).
RUST_FREE = frozenset({"error", "testing"})

#: What a Rust source says outside its comments and literals: comments,
#: strings (raw ones too) and char literals, matched left to right.
_RUST_NOISE = re.compile(
    r"//[^\n]*|/\*.*?\*/|r(#*)\".*?\"\1|b?\"(?:\\.|[^\"\\])*\"|b?'(?:\\.|[^'\\\n])'",
    re.S,
)


def module_names(package: Path) -> dict[str, Path]:
    """Every module of a package, by dotted name.

    Parameters
    ----------
    package : Path
        The package's folder (the one holding its ``__init__.py``); its
        name is the first part of every dotted name.

    Returns
    -------
    dict of str to Path
        Dotted module name to file; a (sub)package is named by its folder
        and maps to its ``__init__.py``. A compiled module is known by its
        type stub (``_core.pyi``), which stands for it.
    """
    names: dict[str, Path] = {}
    sources = [*package.rglob("*.py"), *package.rglob("*.pyi")]
    for path in sorted(sources, key=lambda p: (p.suffix == ".pyi", p)):
        parts = list(path.relative_to(package.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        names.setdefault(".".join(parts), path)
    return names


def _target(name: str, modules: Iterable[str]) -> str | None:
    """The longest known module that ``name`` is or lies inside, if any."""
    known = set(modules)
    parts = name.split(".")
    for end in range(len(parts), 0, -1):
        candidate = ".".join(parts[:end])
        if candidate in known:
            return candidate
    return None


def imports_of(source: str, here: str, is_package: bool, modules: Iterable[str]) -> set[str]:
    """The package's modules that one module imports, wherever the import stands.

    Parameters
    ----------
    source : str
        The module's source code.
    here : str
        Its dotted name.
    is_package : bool
        Whether it is a package's ``__init__.py`` (relative imports then
        start from the package itself).
    modules : iterable of str
        The dotted names of all modules of the package.

    Returns
    -------
    set of str
        The modules imported, at module level, inside functions and classes,
        and under ``if TYPE_CHECKING:`` alike; never ``here`` itself. An
        import of a module inside a package that ``here`` is not part of
        also counts that package (Python runs its ``__init__.py`` first).
    """
    known = set(modules)
    package = here.split(".") if is_package else here.split(".")[:-1]
    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                target = _target(alias.name, known)
                if target is not None:
                    found.add(target)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                start = package[: len(package) - (node.level - 1)]
                base = ".".join(start + ([base] if base else []))
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                target = sub if sub in known else _target(base, known)
                if target is not None:
                    found.add(target)
    # Importing a module runs the packages it lies in first: a module outside
    # a package that imports one of its modules depends on its __init__.py too.
    for target in list(found):
        parts = target.split(".")
        for end in range(1, len(parts)):
            package_name = ".".join(parts[:end])
            if package_name in known and not here.startswith(package_name + "."):
                found.add(package_name)
    found.discard(here)
    return found


def import_graph(package: Path) -> dict[str, set[str]]:
    """Each module of a package, with the package's modules it imports.

    Parameters
    ----------
    package : Path
        The package's folder.

    Returns
    -------
    dict of str to set of str
        Edges ``importer -> imported`` (see :func:`imports_of`).
    """
    names = module_names(package)
    return {
        name: imports_of(path.read_text(encoding="utf-8"), name, path.name == "__init__.py", names)
        for name, path in names.items()
    }


def cycles(graph: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan).

    Parameters
    ----------
    graph : mapping of str to iterable of str
        Edges ``importer -> imported``.

    Returns
    -------
    list of list of str
        Each component's modules, sorted; the components sorted by their
        first module. Empty when the graph has no cycle.
    """
    edges = {v: sorted(set(ws)) for v, ws in graph.items()}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    # Iterative, so that a deep import chain cannot hit the recursion limit.
    for root in sorted(edges):
        if root in index:
            continue
        work: list[tuple[str, int]] = [(root, 0)]
        while work:
            v, i = work.pop()
            if i == 0:
                index[v] = low[v] = len(index)
                stack.append(v)
                on_stack.add(v)
            succ = edges.get(v, [])
            if i < len(succ):
                work.append((v, i + 1))
                w = succ[i]
                if w not in index:
                    work.append((w, 0))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            if low[v] == index[v]:
                comp: list[str] = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    found.append(sorted(comp))
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[v])
    return sorted(found)


def one_cycle(graph: Mapping[str, Iterable[str]], component: list[str]) -> list[str]:
    """One closed import path through a component, from its first module back to it.

    Parameters
    ----------
    graph : mapping of str to iterable of str
        Edges ``importer -> imported``.
    component : list of str
        The modules of one strongly connected component (see :func:`cycles`).

    Returns
    -------
    list of str
        ``[m0, m1, ..., m0]``: each module imports the next (a shortest
        such path, found breadth first inside the component).
    """
    inside = set(component)
    start = component[0]
    came: dict[str, str] = {}
    frontier = [start]
    while frontier:
        following: list[str] = []
        for v in frontier:
            for w in sorted(set(graph.get(v, ())) & inside):
                if w == start:
                    path = [v]
                    while path[-1] != start:
                        path.append(came[path[-1]])
                    return [start, *reversed(path[:-1]), start] if v != start else [start, start]
                if w not in came:
                    came[w] = v
                    following.append(w)
        frontier = following
    return [start]


def long_files(root: Path, limit: int = LIMIT) -> list[tuple[Path, int]]:
    """The source files of the project that have more than ``limit`` lines.

    Parameters
    ----------
    root : Path
        The project's root: ``python/lpvid/**/*.py`` and ``rust/**/*.rs``
        below it are counted.
    limit : int
        Most lines a file may have.

    Returns
    -------
    list of (Path, int)
        Each long file (relative to ``root``) and its number of lines.
    """
    files = sorted([*(root / "python" / "lpvid").rglob("*.py"), *(root / "rust").rglob("*.rs")])
    out: list[tuple[Path, int]] = []
    for path in files:
        with path.open(encoding="utf-8") as handle:
            count = sum(1 for _ in handle)
        if count > limit:
            out.append((path.relative_to(root), count))
    return out


def package_map(readme: str, mark: str = MAP_MARK) -> dict[str, set[str]] | None:
    """The README's package map: each folder with what it may import.

    Parameters
    ----------
    readme : str
        The text of ``README.md``.
    mark : str
        The line right above the table: :data:`MAP_MARK` for the Python
        package's map, :data:`RUST_MAP_MARK` for the Rust crate's.

    Returns
    -------
    dict of str to set of str, or None
        For every row of the table below :data:`MAP_MARK`: the folder named
        in backticks in its first cell (``data/``, without the slash), and
        the names in backticks in its last cell (folders without their
        slash; ``lpvid`` or ``testing`` for top-level modules). None when
        the README has no map.
    """
    lines = readme.splitlines()
    if mark not in lines:
        return None
    found: dict[str, set[str]] = {}
    for line in lines[lines.index(mark) + 1 :]:
        if not line.startswith("|"):
            if found:
                break
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        names = re.findall(r"`([\w.]+)/?`", cells[0])
        if names:
            found[names[0]] = set(re.findall(r"`([\w.]+)/?`", cells[-1]))
    return found


def row_breaks(
    rule: str, table: str, root: str, folders: set[str], the_map: Mapping[str, set[str]]
) -> list[str]:
    """One line per folder of ``root`` without a row in ``table``, and per row without a folder."""
    return [f"{rule}: {root}/{f}/ has no row in {table}" for f in folders - set(the_map)] + [
        f"{rule}: {table} names {f}/, which is not a folder of {root}"
        for f in set(the_map) - folders
    ]


def map_breaks(
    graph: Mapping[str, Iterable[str]], folders: Iterable[str], the_map: Mapping[str, set[str]]
) -> list[str]:
    """What the package map gets wrong about the import graph.

    Parameters
    ----------
    graph : mapping of str to iterable of str
        The package's import graph (:func:`import_graph`).
    folders : iterable of str
        The folders (sub-packages) of ``python/lpvid``, by name.
    the_map : mapping of str to set of str
        The map (:func:`package_map`).

    Returns
    -------
    list of str
        One line per folder missing from the map or named by it but absent,
        and per import that the map does not allow (see the module's
        docstring), sorted.
    """
    folders = set(folders)
    breaks = row_breaks("package map", "README.md's map", "python/lpvid", folders, the_map)

    def place(module: str) -> str:
        parts = module.split(".")
        if len(parts) == 1:
            return "lpvid"
        return parts[1]

    # One line per importer and folder it may not import (naming the
    # module, not the package's __init__ that comes with it).
    seen: dict[tuple[str, str], str] = {}
    for importer, targets in graph.items():
        here = place(importer)
        if here not in folders or here not in the_map:
            continue
        for target in sorted(targets, key=len):
            there = place(target)
            if not (there == here or FREE.match(target) or there in the_map[here]):
                seen[(importer, there)] = target
    for (importer, there), target in seen.items():
        here = place(importer)
        what = f"{there}/" if there in folders else there
        breaks.append(
            f"package map: {importer} imports {target}, "
            f"but the map does not let {here}/ import {what}"
        )
    return sorted(set(breaks))


def rust_uses(source: str) -> set[str]:
    """The first names of the ``crate::`` paths of one Rust source.

    Parameters
    ----------
    source : str
        The text of a ``.rs`` file.

    Returns
    -------
    set of str
        For every ``crate::x...`` outside comments, strings and char
        literals: ``x``; for a group ``crate::{x::a, y}``: ``x`` and ``y``.
    """
    code = _RUST_NOISE.sub(lambda m: '""' if m.group(0).endswith('"') else " ", source)
    found: set[str] = set()
    for match in re.finditer(r"\bcrate\s*::\s*", code):
        at = match.end()
        if code.startswith("{", at):
            depth, item, items = 0, "", []
            for char in code[at:]:
                depth += (char == "{") - (char == "}")
                if depth == 0:
                    break
                if depth == 1 and char == ",":
                    items.append(item)
                    item = ""
                elif depth >= 1 and not (depth == 1 and char == "{"):
                    item += char
            items.append(item)
            found.update(m.group(1) for i in items if (m := re.match(r"\s*(\w+)", i)))
        elif name := re.match(r"\w+", code[at:]):
            found.add(name.group(0))
    return found


def _reexports(lib: str) -> dict[str, str]:
    """The names ``lib.rs`` re-exports (``pub use x::...::Name``), each with its module ``x``."""
    code = _RUST_NOISE.sub(" ", lib)
    found: dict[str, str] = {}
    for module, rest in re.findall(r"\bpub\s+use\s+(\w+)\s*::([^;]*);", code):
        tail = rest[rest.index("{") :] if "{" in rest else rest.rsplit("::", 1)[-1]
        for name in re.findall(r"\w+", tail):
            found.setdefault(name, module)
    return found


def rust_folders(crate: Path) -> list[str]:
    """The folders of a Rust crate's source directory (``rust/``), by name."""
    return sorted(p.name for p in crate.iterdir() if p.is_dir() and any(p.rglob("*.rs")))


def rust_use_graph(crate: Path) -> dict[str, set[str]]:
    """Each source file of the crate with the top-level modules it uses.

    Parameters
    ----------
    crate : Path
        The crate's source directory (``rust/``, holding ``lib.rs``).

    Returns
    -------
    dict of str to set of str
        File (relative to ``crate``, with ``/``) to the crate's top-level
        modules named by its ``crate::`` paths (:func:`rust_uses`), a name
        re-exported by ``lib.rs`` replaced by the module it comes from.
    """
    lib = crate / "lib.rs"
    reexported = _reexports(lib.read_text(encoding="utf-8")) if lib.is_file() else {}
    return {
        path.relative_to(crate).as_posix(): {
            reexported.get(name, name) for name in rust_uses(path.read_text(encoding="utf-8"))
        }
        for path in sorted(crate.rglob("*.rs"))
    }


def rust_map_breaks(
    graph: Mapping[str, Iterable[str]], folders: Iterable[str], the_map: Mapping[str, set[str]]
) -> list[str]:
    """What the README's Rust map gets wrong about the crate's ``crate::`` paths.

    Parameters
    ----------
    graph : mapping of str to iterable of str
        The crate's files with the top-level modules they use
        (:func:`rust_use_graph`).
    folders : iterable of str
        The folders of ``rust/`` (:func:`rust_folders`).
    the_map : mapping of str to set of str
        The map (:func:`package_map` with :data:`RUST_MAP_MARK`).

    Returns
    -------
    list of str
        One line per folder missing from the map or named by it but absent,
        per use the map does not allow, and per circle of folders that use
        each other (see the module's docstring), sorted.
    """
    folders = set(folders)
    breaks = row_breaks("rust map", "README.md's Rust map", "rust", folders, the_map)
    between: dict[str, set[str]] = {f: set() for f in folders}
    for path, used in graph.items():
        here = path.split("/")[0]
        if here not in folders:
            continue
        for there in sorted(set(used) - RUST_FREE - {here}):
            between[here].add(there)
            if here in the_map and there not in the_map[here]:
                what = f"{there}/" if there in folders else there
                breaks.append(
                    f"rust map: rust/{path} uses crate::{there}, "
                    f"but the map does not let {here}/ use {what}"
                )
    for component in cycles(between):
        breaks.append(
            f"rust map: folders in a circle: {' -> '.join(one_cycle(between, component))}"
        )
    return sorted(set(breaks))


def main(argv: list[str] | None = None) -> int:
    """Check a project and print what breaks the house rules.

    Parameters
    ----------
    argv : list of str, optional
        The arguments after the program name: at most a project root
        (default: the current directory). None: ``sys.argv[1:]``.

    Returns
    -------
    int
        0 when there is no cycle, no long file and both maps are true, 1 otherwise.
    """
    args = sys.argv[1:] if argv is None else argv
    root = Path(args[0] if args else ".").resolve()
    package = root / "python" / "lpvid"
    if not (package / "__init__.py").is_file():
        print(f"house check: no package at {package}", file=sys.stderr)
        return 1
    graph = import_graph(package)
    found = cycles(graph)
    for component in found:
        print(f"import cycle: {' -> '.join(one_cycle(graph, component))}")
        if len(component) > len(set(one_cycle(graph, component))):
            print(f"  (all of: {', '.join(component)})")
    long = long_files(root)
    for path, count in long:
        print(f"long file: {path} {count} lines (limit {LIMIT})")
    readme = root / "README.md"
    the_map = package_map(readme.read_text(encoding="utf-8")) if readme.is_file() else None
    if the_map is None:
        breaks = [f"package map: README.md has no map (the line {MAP_MARK!r} above a table)"]
    else:
        folders = [p.parent.name for p in package.glob("*/__init__.py")]
        breaks = map_breaks(graph, folders, the_map)
    for line in breaks:
        print(line)
    rust_breaks = _rust_breaks(root, readme)
    for line in rust_breaks:
        print(line)
    print(
        f"house: {len(found)} import cycle(s), {len(long)} file(s) over {LIMIT} lines, "
        f"{len(breaks)} package map error(s), {len(rust_breaks)} Rust map error(s)"
    )
    return 1 if found or long or breaks or rust_breaks else 0


def _rust_breaks(root: Path, readme: Path) -> list[str]:
    """The Rust map's breaks (:func:`rust_map_breaks`); none when ``rust/`` has no folder."""
    crate = root / "rust"
    folders = rust_folders(crate) if crate.is_dir() else []
    if not folders:
        return []
    text = readme.read_text(encoding="utf-8") if readme.is_file() else ""
    the_map = package_map(text, RUST_MAP_MARK)
    if the_map is None:
        return [f"rust map: README.md has no Rust map (the line {RUST_MAP_MARK!r} above a table)"]
    return rust_map_breaks(rust_use_graph(crate), folders, the_map)


if __name__ == "__main__":
    raise SystemExit(main())
