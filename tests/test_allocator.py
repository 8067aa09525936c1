"""The allocator settings of the hconv process (glibc's malloc thresholds)."""

from __future__ import annotations

import platform
import subprocess
import sys

import pytest

from hconv.kernels import allocator


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="the settings apply to glibc's malloc only")
def test_allocator_tune_applies_on_glibc():
    # in a fresh process, so that this test process's allocator is left as it was
    code = "from hconv.kernels import allocator; print(allocator.tune())"
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True).stdout
    assert out.strip() == "True"


def test_allocator_tune_never_raises_off_glibc(monkeypatch):
    monkeypatch.setattr(allocator.sys, "platform", "darwin")
    assert allocator.tune() is False
