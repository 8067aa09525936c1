"""Fixtures; the shared helper functions are in helpers.py."""

from __future__ import annotations

import os
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest
from helpers import S3_ENV, free_port, need


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


@pytest.fixture(scope="session")
def s3_server(tmp_path_factory):
    """The URL of a local S3-compatible server (moto's server mode, the ``test-s3`` extra) on
    127.0.0.1, running as its own process for the test session (one per xdist worker: each test
    has a fresh bucket of its own, :func:`s3`); skips without moto."""
    need("moto.server")  # the test-s3 extra: moto's S3 backend and flask for its server mode
    need("flask")
    port = free_port()
    log = tmp_path_factory.mktemp("moto") / "server.log"
    with open(log, "wb") as f:
        server = subprocess.Popen(
            [sys.executable, "-m", "moto.server", "-H", "127.0.0.1", "-p", str(port)], stdout=f, stderr=f
        )
    url = f"http://127.0.0.1:{port}"
    deadline = time.time() + 30
    while True:
        try:
            urllib.request.urlopen(url + "/", timeout=1).close()
            break
        except OSError:
            if server.poll() is not None or time.time() > deadline:
                server.kill()
                pytest.fail(f"moto's server did not start: {log.read_text()[-2000:]}")
            time.sleep(0.1)
    yield url
    server.terminate()
    server.wait(timeout=10)


@pytest.fixture
def s3(s3_server, monkeypatch, tmp_path):
    """A fresh bucket on the server, with credentials in the environment; yields (url, fs, bucket)."""
    import pyarrow.fs as pafs

    for name in list(os.environ):
        if name.startswith("AWS_"):
            monkeypatch.delenv(name)
    for name, value in S3_ENV.items():
        monkeypatch.setenv(name, value)
    monkeypatch.setenv("AWS_CONFIG_FILE", str(tmp_path / "no-aws-config"))
    monkeypatch.setenv("AWS_SHARED_CREDENTIALS_FILE", str(tmp_path / "no-aws-credentials"))
    fs = pafs.S3FileSystem(endpoint_override=s3_server, allow_bucket_creation=True)
    bucket = f"hconv-{os.urandom(4).hex()}"
    fs.create_dir(bucket)
    return s3_server, fs, bucket
