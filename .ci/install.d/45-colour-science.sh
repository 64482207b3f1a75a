#!/usr/bin/env bash
# colour-science and numpy: the independent oracle of the paper's Table 1
# (tests/tools/table1_oracle.py, run by tests/all/table1_oracle.rs) computes Lab, CIEDE2000 and the
# Finlayson 2015 expansions with them.
set -euo pipefail
if ! python3 -c 'import colour, numpy' >/dev/null 2>&1; then
  pip install -q colour-science numpy || pip install -q --break-system-packages colour-science numpy
fi
python3 -c 'import colour, numpy'
