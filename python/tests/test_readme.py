"""The README's Python block runs as written, against the installed package (what `pip install .`
gave this interpreter)."""

import re

from conftest import ROOT


def test_the_readme_python_block_runs():
    text = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert blocks, "the README has a Python block"
    scope = {}
    exec(compile(blocks[0], "README.md", "exec"), scope)
    assert scope["xyz"].shape == (4, 6, 3)
    assert scope["model"].kind == "nsrm"
