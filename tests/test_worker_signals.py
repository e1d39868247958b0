"""A forked worker stopped at the instant it starts never runs the parent's signal handler.

A run stops its workers with SIGTERM while its own SIGTERM handler raises ``Terminated``. A
child stopped before it had set its own handling used to run that handler: the exception
unwound the parent's stack in the child (under pytest-xdist, a second "worker" that reported a
keyboard interrupt), or was swallowed so that the child never ended and the run hung in
``stop()``. The race is small, so each check starts and stops many workers in a subprocess.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

from yafs_safetail.runs.workers import can_fork

pytestmark = pytest.mark.skipif(not can_fork(), reason="forked workers need fork (not on this platform)")

_STARTS = 200

_SCRIPT = textwrap.dedent("""
    import os, signal, sys
    from yafs_safetail.cli import raise_terminated
    from yafs_safetail.runs.workers import ForkedWorker, become_worker

    def wait_for_the_parent(channel):
        become_worker()
        channel.recv()

    signal.signal(signal.SIGTERM, raise_terminated)
    parent = os.getpid()
    exit_codes = set()
    for _ in range(int(sys.argv[1])):
        try:
            worker = ForkedWorker(wait_for_the_parent, (), "stopped-at-once", duplex=True)
            worker._process.terminate()
            worker._process.join(timeout=10)
        except BaseException as error:
            if os.getpid() != parent:
                print("a child ran the parent's handler:", type(error).__name__, flush=True)
                os._exit(0)
            raise
        if worker._process.is_alive():
            worker._process.kill()
            print("a child swallowed SIGTERM and never ended", flush=True)
            sys.exit(0)
        exit_codes.add(worker._process.exitcode)
    print("exit codes", sorted(exit_codes), flush=True)
""")


def test_a_worker_stopped_as_it_starts_dies_of_sigterm_and_nothing_else():
    done = subprocess.run([sys.executable, "-c", _SCRIPT, str(_STARTS)], capture_output=True, text=True,
                          timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"exit codes [{-15}]", done.stdout + done.stderr
