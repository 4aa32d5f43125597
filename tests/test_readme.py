"""The README's short example runs as written and says what it claims."""

from __future__ import annotations

import re
from pathlib import Path

import dea_opt as dea

ROOT = Path(__file__).resolve().parents[1]


def test_short_example_runs(capsys):
    readme = (ROOT / "README.md").read_text()
    section = readme.split("## A short example", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    namespace: dict = {}
    exec(compile(code, "README.md", "exec"), namespace)
    solution = namespace["solution"]
    assert isinstance(solution, dea.Solution) and solution.success
    assert solution.method == "newton"  # auto: Newton first, certified
    assert abs(solution.contact_force[2] - 10.0) < 1e-8
    assert capsys.readouterr().out.strip()
