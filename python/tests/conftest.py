"""Shared fixtures of the pytest suite of the nsrm Python bindings.

A test whose prerequisite is absent (the `nsrm` binary, the development photographs in
../shared) calls `skip_or_fail(reason)`: it skips with the reason locally and fails under
CI=true, as the Rust tests' `skip_or_fail` does.
"""

import os
import pathlib
import shutil

import numpy as np
import pytest

import nsrm

ROOT = pathlib.Path(__file__).resolve().parents[2]


def skip_or_fail(reason: str) -> None:
    if os.environ.get("CI") == "true":
        pytest.fail(f"{reason} (a prerequisite of this test, required under CI=true)")
    pytest.skip(reason)


def shared_dir() -> pathlib.Path:
    """`../shared` beside the checkout, or `$NSRM_SHARED`."""
    env = os.environ.get("NSRM_SHARED")
    p = ROOT.parent / "shared"
    if not p.exists() and env:
        return pathlib.Path(env)
    return p


@pytest.fixture(scope="session")
def nsrm_bin() -> str:
    """The `nsrm` binary: `$NSRM_BIN` (tests/all/python.rs passes its own), else one on PATH."""
    b = os.environ.get("NSRM_BIN") or shutil.which("nsrm")
    if not b or not os.path.exists(b):
        skip_or_fail("the nsrm binary is absent: set NSRM_BIN (cargo test runs this suite with it)")
    return b


@pytest.fixture(scope="session")
def d65():
    """The built-in training set: Nikon D5100 under D65, ColorChecker 24."""
    return nsrm.builtin_training("nikon-d5100", "D65", "cc24")


@pytest.fixture(scope="session")
def rng():
    return np.random.default_rng(39)
