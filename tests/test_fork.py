"""A process forked from one that ran lpvid runs it too (the core's loops on a pool of its own).

Before, the child's first parallel loop waited for good for the threads of
the parent's pool, which a fork does not copy. Each run is a process of its
own, so that the test process itself is never forked.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

# The parent identifies the gantry, forks, and the child identifies it
# again (and, in a grandchild, once more); each prints a hash of its theta.
# A child that does not end within its deadline is killed and said.
_FORKED = """
import hashlib, os, sys, time, warnings
import lpvid

ds = lpvid.datasets.gantry(seed=0)


def run():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = lpvid.identify(ds.identification, ds.order, ds.basis, fixed=ds.fixed,
                           validation=ds.validation)
    return hashlib.sha1(r.model.theta.tobytes()).hexdigest()


def forked(depth):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # 3.12+: fork of a threaded process
        pid = os.fork()
    if pid == 0:
        code = 1
        try:
            print(f"child{depth}", run(), flush=True)
            code = 0 if depth == 2 else forked(depth + 1)
        finally:
            os._exit(code)
    # A child's own child gets half its time: it is killed and said before
    # the child is (an orphan left hanging would keep the output open).
    deadline = time.monotonic() + float(sys.argv[1]) / depth
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return os.waitstatus_to_exitcode(status)
        time.sleep(0.05)
    os.kill(pid, 9)
    os.waitpid(pid, 0)
    print(f"child{depth} hung", flush=True)
    return 2


print("parent", run(), flush=True)
sys.exit(forked(1))
"""


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_a_forked_process_identifies_as_its_parent_did():
    """The child and its own child run identify to the parent's model, bit for bit."""
    done = subprocess.run(
        [sys.executable, "-c", _FORKED, "120"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    lines = dict(line.split() for line in done.stdout.splitlines())
    assert done.returncode == 0, (done.stdout, done.stderr)
    assert set(lines) == {"parent", "child1", "child2"}
    assert lines["child1"] == lines["parent"] and lines["child2"] == lines["parent"]
