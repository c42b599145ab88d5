"""Building the command line's parser imports no command's implementation.

Every ``bullet-dlo`` process (each test, capture and demo subprocess) builds the whole parser; the DEFORM options
lived beside their fit code, whose SciPy optimisers and splines cost about 0.15-0.3 s of CPU in every process."""
from __future__ import annotations

import subprocess
import sys


def test_the_parser_does_not_import_the_validation_fits():
    code = ("import sys; from bullet_dlo.cli.main import build_parser; build_parser(); "
            "print(sorted(m for m in ('bullet_dlo.reality.deform', 'bullet_dlo.reality.beam', 'scipy.interpolate') "
            "if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"
