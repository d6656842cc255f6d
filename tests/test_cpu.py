"""The processor check made before the compiled core is loaded (lpvid._cpu)."""

import subprocess
import sys

import pytest

from lpvid import _core, _cpu


def checked_features():
    """The features of this build that numpy reports, and numpy's report."""
    cpu = _cpu.processor_features()
    recorded = _cpu.build_features(_core.__file__)
    checked = [f for f in recorded if _cpu.numpy_name(f) in cpu]
    if not checked:
        pytest.skip("numpy reports none of the features this build uses")
    return checked, cpu


def test_the_file_records_what_the_loaded_module_was_built_with():
    recorded = _cpu.build_features(_core.__file__)
    assert recorded and recorded == _cpu.parse(_core.__target_features__.encode())


def test_this_processor_passes_and_one_lacking_a_feature_is_refused():
    checked, cpu = checked_features()
    _cpu.check_processor(cpu)  # this machine runs the build: no error
    lacking = {**cpu, _cpu.numpy_name(checked[-1]): False}
    assert _cpu.missing(checked, lacking) == [checked[-1]]
    with pytest.raises(ImportError, match=checked[-1].upper()) as err:
        _cpu.check_processor(lacking)
    assert "target-cpu=native" in str(err.value)


def test_names_map_to_numpy_spelling():
    cpu = {"AVX2": True, "FMA3": False, "BMI": False, "SSE41": False, "CX16": True}
    features = ["avx2", "fma", "bmi1", "sse4.1", "cmpxchg16b", "xsave"]
    assert _cpu.missing(features, cpu) == ["fma", "bmi1", "sse4.1"]


def test_parse_reads_between_the_marker_and_the_semicolon():
    assert _cpu.parse(b"\0junk lpvid-target-features:avx,avx2,fma;more") == ["avx", "avx2", "fma"]
    assert _cpu.parse(b"lpvid-target-features:;") == []
    assert _cpu.parse(b"no marker here") == []


def test_import_is_refused_before_the_core_loads():
    """A fresh interpreter whose numpy reports one of the build's features absent."""
    checked, _ = checked_features()
    code = (
        "import sys\n"
        "try:\n"
        "    from numpy._core import _multiarray_umath as m\n"
        "except ImportError:\n"
        "    from numpy.core import _multiarray_umath as m\n"
        f"m.__cpu_features__[{_cpu.numpy_name(checked[-1])!r}] = False\n"
        "try:\n"
        "    import lpvid\n"
        "except ImportError as exc:\n"
        "    print('refused:', exc)\n"
        "print('core loaded:', 'lpvid._core' in sys.modules)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert "refused:" in out.stdout and checked[-1].upper() in out.stdout, out.stdout
    assert "core loaded: False" in out.stdout
