"""The README's ten-line example runs and prints the paper's P5P9 case-2 force (Table 1,
44.3 N, within 1 %)."""

import contextlib
import io
import re
from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"


def test_readme_example_runs():
    code = re.search(r"```python\n(.*?)```", README.read_text(), re.S).group(1)
    output = io.StringIO()
    with contextlib.redirect_stdout(output):
        exec(compile(code, "README.md", "exec"), {})
    assert abs(float(output.getvalue().split()[0]) / 44.3 - 1) < 0.01
