"""The processor check made before lpvid's compiled core is loaded.

The core is compiled for x86-64-v3 by default (``.cargo/config.toml``: AVX2,
FMA, BMI1/2, F16C, LZCNT, MOVBE), so that a build runs alike on every such
processor. Code built for AVX2 may use it anywhere, the module's
initialisation included, so on an older processor loading the module could
die of an illegal instruction instead of raising. The build therefore
writes the instruction-set extensions it may use into the module as one
string (``lpvid-target-features:avx,avx2,...;``, see ``build.rs``), and
this module finds it in the file and compares it with the processor's
features as numpy detects them, before anything loads the module.
Extensions numpy does not report (``xsave``, ``fxsr``, ...) are not checked.
Importing this module makes the check; ``lpvid/__init__.py`` imports it first.

It also checks the route switch ``LPVID_KERNEL`` (``auto``, ``avx512``,
``avx2``, ``portable``; ``rust/base/route.rs``): the core's hand-written vector
code runs the processor's widest route unless the variable asks for a
narrower one, so that the route of a processor without AVX-512 can be run
and tested on one with it. An unknown name, or a route this processor
cannot run, is refused here with an ImportError (the core itself would
fall back to the widest route).
"""

from __future__ import annotations

import importlib.util
import mmap
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

MARKER = b"lpvid-target-features:"

# rustc's names that numpy spells otherwise; the rest are upper-cased
# without dots (sse4.1 -> SSE41, avx512f -> AVX512F).
_NUMPY_NAMES = {"bmi1": "BMI", "fma": "FMA3", "cmpxchg16b": "CX16"}

REBUILD = (
    'build it from source on this machine: RUSTFLAGS="-C target-cpu=native" pip install . '
    "in lpvid's source directory (docs/development.md)"
)


def parse(text: bytes) -> list[str]:
    """The features listed after :data:`MARKER` in ``text`` (empty list if none)."""
    start = text.find(MARKER)
    if start < 0:
        return []
    start += len(MARKER)
    end = text.find(b";", start)
    if end < 0:
        return []
    body = text[start:end].decode("ascii")
    return [f for f in body.split(",") if f]


def build_features(path: str | Path) -> list[str] | None:
    """The extensions the compiled module at ``path`` was built to use, None if unrecorded."""
    with open(path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
        start = mm.find(MARKER)
        if start < 0:
            return None
        end = mm.find(b";", start)
        if end < 0:
            return None
        return parse(mm[start : end + 1])


def processor_features() -> Mapping[str, bool]:
    """The processor's features as numpy detected them (numpy's names: AVX2, FMA3, ...)."""
    try:
        from numpy._core._multiarray_umath import __cpu_features__
    except ImportError:  # numpy < 2
        from numpy.core._multiarray_umath import __cpu_features__
    return dict(__cpu_features__)


def numpy_name(feature: str) -> str:
    """The name numpy gives one of rustc's target features (``sse4.1`` -> ``SSE41``)."""
    return _NUMPY_NAMES.get(feature, feature.replace(".", "").upper())


def missing(features: Iterable[str], cpu: Mapping[str, bool]) -> list[str]:
    """The build's ``features`` (rustc's names) that ``cpu`` (numpy's names) reports absent."""
    return [f for f in features if not cpu.get(numpy_name(f), True)]


#: The environment variable that chooses the core's route (read once, at import).
SWITCH = "LPVID_KERNEL"

#: Each route the switch names, with the processor features (numpy's names) it needs.
ROUTES: dict[str, tuple[str, ...]] = {
    "avx512": ("AVX512F", "AVX2", "FMA3"),
    "avx2": ("AVX2", "FMA3"),
    "portable": (),
}


def check_route(
    environ: Mapping[str, str] | None = None, cpu: Mapping[str, bool] | None = None
) -> str | None:
    """The route ``LPVID_KERNEL`` asks for (None: the processor's widest).

    Parameters
    ----------
    environ : mapping of str to str, optional
        The environment; default ``os.environ``.
    cpu : mapping of str to bool, optional
        The processor's features in numpy's names; default: numpy's detection.

    Returns
    -------
    str or None

    Raises
    ------
    ImportError
        When the variable names no route, or a route whose features this
        processor lacks.

    """
    value = (os.environ if environ is None else environ).get(SWITCH, "").strip().lower()
    if value in ("", "auto"):
        return None
    if value not in ROUTES:
        raise ImportError(
            f"{SWITCH}={value!r}: expected one of auto, {', '.join(ROUTES)} "
            "(the route of lpvid's vector kernels; docs/development.md)"
        )
    cpu = processor_features() if cpu is None else cpu
    lacking = [f for f in ROUTES[value] if not cpu.get(f, False)]
    if lacking:
        raise ImportError(
            f"{SWITCH}={value!r}: this processor lacks {', '.join(lacking)}; "
            f"choose a narrower route ({', '.join(r for r in ROUTES if r != value)}) or unset it"
        )
    return value


def kernel_route() -> str:
    """The route of the compiled core's vector kernels that this process runs.

    ``"avx512"``, ``"avx2"`` or ``"portable"``: the processor's widest, or
    the narrower one the environment variable ``LPVID_KERNEL`` asked for
    when lpvid was imported (see ``docs/development.md``, "Routes"). Every
    route gives the same models; only the speed differs.

    Returns
    -------
    str

    Examples
    --------
    >>> import lpvid
    >>> lpvid.kernel_route() in ("avx512", "avx2", "portable")
    True

    """
    from lpvid import _core

    return _core.kernel_route()


def check_processor(cpu: Mapping[str, bool] | None = None) -> None:
    """Raise ImportError if this processor lacks an extension the compiled core uses.

    Parameters
    ----------
    cpu : mapping of str to bool, optional
        The processor's features in numpy's names; default: numpy's detection.

    Raises
    ------
    ImportError
        Naming the extensions the build uses and the processor lacks, and how
        to build lpvid for this processor.

    """
    spec = importlib.util.find_spec("lpvid._core")
    if spec is None or spec.origin is None or not Path(spec.origin).is_file():
        return  # no compiled core: importing it will say so
    features = build_features(spec.origin)
    if not features:
        return
    absent = missing(features, processor_features() if cpu is None else cpu)
    if absent:
        names = ", ".join(f.upper() for f in absent)
        raise ImportError(
            f"lpvid's compiled core ({spec.origin}) was built for processors with "
            f"{names}, which this processor lacks (as numpy detects its features); "
            f"{REBUILD}."
        )


check_processor()
check_route()
