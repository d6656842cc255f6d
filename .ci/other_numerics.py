"""The environment of CI's second flavour: numpy's numerics on other kernels.

``python .ci/other_numerics.py`` prints shell ``export`` lines: numpy's
OpenBLAS on another kernel than the one it chose for this processor
(Sandybridge: AVX without FMA; Nehalem where Sandybridge is the choice), and
numpy's SIMD dispatch off (every dispatched feature disabled, so exp, sin,
log, power, ... run numpy's baseline code). ``python .ci/other_numerics.py
--check`` fails unless OpenBLAS runs the kernel that OPENBLAS_CORETYPE asks
for (OpenBLAS ignores a name it does not know).
"""

import os
import sys

import numpy  # noqa: F401  (threadpoolctl sees the libraries loaded)
import scipy.linalg  # noqa: F401
import threadpoolctl


def openblas_kernels() -> set[str]:
    """The kernels of the OpenBLAS libraries that numpy and scipy loaded."""
    return {
        i["architecture"]
        for i in threadpoolctl.threadpool_info()
        if i["internal_api"] == "openblas"
    }


def main() -> None:
    """Print the exports, or check with --check."""
    if sys.argv[1:] == ["--check"]:
        want = os.environ["OPENBLAS_CORETYPE"]
        got = openblas_kernels()
        if got != {want}:
            sys.exit(f"OpenBLAS runs {got}, not OPENBLAS_CORETYPE={want}")
        print(f"OpenBLAS on {want}; numpy's dispatch off: {os.environ['NPY_DISABLE_CPU_FEATURES']}")
        return
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__
    except ImportError:  # numpy < 2
        from numpy.core._multiarray_umath import __cpu_dispatch__
    other = "Nehalem" if "Sandybridge" in openblas_kernels() else "Sandybridge"
    print(f"export OPENBLAS_CORETYPE={other}")
    print(f"export NPY_DISABLE_CPU_FEATURES='{' '.join(__cpu_dispatch__)}'")


if __name__ == "__main__":
    main()
