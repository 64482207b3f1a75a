//! The Python bindings (crates/nsrm-py, python/nsrm): the pytest suite `python/tests`, run by the
//! interpreter of `target/python-venv`, where `.ci/install.d/70-python.sh` installs the wheel
//! built from this checkout with numpy, pytest, colour-science and tifffile. The suite judges
//! `nsrm.fit` against colour-science's fits, `Model.apply` against `nsrm apply` bit for bit
//! (this binary's `nsrm`, passed as `NSRM_BIN`), `eval_loo` against `nsrm eval --json`, and
//! `read_chart` on the development photographs.

use crate::common;
use std::path::Path;
use std::process::Command;

const SCRIPT: &str = ".ci/install.d/70-python.sh";

#[test]
fn pytest_suite_passes_against_the_installed_wheel() {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let python = root.join("target/python-venv/bin/python");
    if !python.exists() {
        common::skip(&format!(
            "{} is absent: run {SCRIPT} (builds the nsrm wheel into a venv with pytest and colour-science)",
            python.display()
        ));
        return;
    }
    // The wheel must be of these sources: a stale one would test other code.
    let fresh = Command::new("bash")
        .arg(root.join(SCRIPT))
        .arg("--check")
        .status()
        .expect("bash runs");
    if !fresh.success() {
        common::skip(&format!(
            "the nsrm wheel in target/python-venv is older than the sources: run {SCRIPT}"
        ));
        return;
    }
    let mut pytest = Command::new(&python);
    pytest
        .args([
            "-m",
            "pytest",
            "python/tests",
            "-q",
            "-p",
            "no:cacheprovider",
        ])
        .current_dir(root)
        .env("NSRM_BIN", env!("CARGO_BIN_EXE_nsrm"))
        .env_remove("NSRM_ADAPTER");
    if let Some(d) = common::xdg_runtime_dir() {
        pytest.env("XDG_RUNTIME_DIR", d);
    }
    let out = pytest.output().expect("the venv's python runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    eprintln!("{stdout}{stderr}");
    assert!(
        out.status.success(),
        "pytest python/tests failed:\n{stdout}\n{stderr}"
    );
}
