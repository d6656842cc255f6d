"""The environments of CI's later flavours: other numerics, and a processor without AVX-512.

``python .ci/other_numerics.py`` prints shell ``export`` lines: numpy's
OpenBLAS on another kernel than the one it chose for this processor
(Sandybridge: AVX without FMA; Nehalem where Sandybridge is the choice), and
numpy's SIMD dispatch off (every dispatched feature disabled, so exp, sin,
log, power, ... run numpy's baseline code).

``python .ci/other_numerics.py --without-avx512`` prints the exports that
make this process compute as one on a processor with AVX2 and FMA but
without AVX-512 does (most laptops, AMD Zen 2 and 3): lpvid's core on its
AVX2 route (``LPVID_KERNEL=avx2``, docs/development.md, "Routes") and
numpy's dispatch without its AVX-512 targets (``X86_V4``, ``AVX512_*``),
and OpenBLAS on its Haswell kernels (those of Intel's AVX2 processors and of
AMD's Zen 1 to 3, which OpenBLAS runs on the Haswell kernels too; on an
AVX-512 processor it would choose SkylakeX or later).

``python .ci/other_numerics.py --check`` fails unless OpenBLAS runs the
kernel that OPENBLAS_CORETYPE asks for (OpenBLAS ignores a name it does not
know), numpy runs none of the targets NPY_DISABLE_CPU_FEATURES names, and
lpvid's core runs the route LPVID_KERNEL names (where they are set).
"""

import os
import sys

import numpy  # noqa: F401  (threadpoolctl sees the libraries loaded)
import scipy.linalg  # noqa: F401
import threadpoolctl

try:
    from numpy._core import _multiarray_umath as umath
except ImportError:  # numpy < 2
    from numpy.core import _multiarray_umath as umath


def openblas_kernels() -> set[str]:
    """The kernels of the OpenBLAS libraries that numpy and scipy loaded."""
    return {
        i["architecture"]
        for i in threadpoolctl.threadpool_info()
        if i["internal_api"] == "openblas"
    }


def avx512_targets() -> list[str]:
    """The dispatch targets of numpy that need AVX-512 (numpy 2: X86_V4, AVX512_ICL, ...)."""
    return [t for t in umath.__cpu_dispatch__ if t == "X86_V4" or t.startswith("AVX512")]


def check() -> None:
    """Exit with a message unless the environment asked for is the one in force."""
    said = []
    want = os.environ.get("OPENBLAS_CORETYPE")
    if want:
        got = openblas_kernels()
        if got != {want}:
            sys.exit(f"OpenBLAS runs {got}, not OPENBLAS_CORETYPE={want}")
        said.append(f"OpenBLAS on {want}")
    off = os.environ.get("NPY_DISABLE_CPU_FEATURES", "").split()
    if off:
        on = [t for t in off if umath.__cpu_features__.get(t)]
        if on:
            sys.exit(f"numpy still runs {on} (NPY_DISABLE_CPU_FEATURES={' '.join(off)})")
        said.append(f"numpy's dispatch off: {' '.join(off)}")
    route = os.environ.get("LPVID_KERNEL")
    if route:
        import lpvid

        if lpvid.kernel_route() != route:
            sys.exit(f"lpvid's core runs {lpvid.kernel_route()}, not LPVID_KERNEL={route}")
        said.append(f"lpvid's core on its {route} route")
    print("; ".join(said) or "nothing asked for")


def main() -> None:
    """Print the exports, or check with --check."""
    if sys.argv[1:] == ["--check"]:
        check()
        return
    if sys.argv[1:] == ["--without-avx512"]:
        print("export LPVID_KERNEL=avx2")
        print("export OPENBLAS_CORETYPE=Haswell")
        print(f"export NPY_DISABLE_CPU_FEATURES='{' '.join(avx512_targets())}'")
        return
    if sys.argv[1:]:
        sys.exit(f"usage: {sys.argv[0]} [--check | --without-avx512]")
    other = "Nehalem" if "Sandybridge" in openblas_kernels() else "Sandybridge"
    print(f"export OPENBLAS_CORETYPE={other}")
    print(f"export NPY_DISABLE_CPU_FEATURES='{' '.join(umath.__cpu_dispatch__)}'")


if __name__ == "__main__":
    main()
