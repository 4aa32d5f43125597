"""The README: at most 200 lines, its two set-up commands exactly as CI and users run them, and
its short example runs as written and says what it claims."""

from __future__ import annotations

import re
from pathlib import Path

import dea_opt as dea

ROOT = Path(__file__).resolve().parents[2]


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


def test_the_readme_is_short_and_keeps_its_two_commands():
    readme = (ROOT / "README.md").read_text()
    assert len(readme.splitlines()) <= 200
    assert "python3 -m venv .venv && .venv/bin/pip install . && .venv/bin/dea-opt demo\n" in readme
    assert 'python3 -m venv .venv && .venv/bin/pip install ".[dev]" && .venv/bin/python -m pytest -q -n 2\n' in readme
    assert "sphinx-build -W -n -b html docs docs/_build/html" in readme  # how to build the site
    pictures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", readme)
    assert len(pictures) == 1 and (ROOT / pictures[0]).read_bytes()[:4] == b"\x89PNG"
