"""The gallery: ``examples/`` and the tutorial, run by sphinx-gallery when the site is built.

Each example is a script with an ``--out`` option whose figures are PNG files it writes (it
closes its Matplotlib figures). The build runs each as it stands, into a folder of its own under
``docs/_build``, at ``--coarse`` when the script has that option (the setting the tests use:
seconds, not minutes; a script that takes seconds anyway, ``tka_joint.py``, has none), and
:class:`PngScraper` puts on the page every PNG the script wrote. The tutorial draws with
Matplotlib, whose figures sphinx-gallery's own scraper collects.
"""

from __future__ import annotations

import shutil
from pathlib import Path

#: Where the examples write their outputs during a build (outside the sources).
OUTPUT = "_build/gallery-output"


def _guard_exit() -> None:
    """Make an example's ``sys.exit`` end its run, not the build.

    sphinx-gallery runs a script's blocks in the build's own process and catches ``Exception``
    only: a script ending with ``sys.exit(0)`` (as a command-line tool does) would end
    ``sphinx-build`` itself, with exit code 0 and half a site. Here ``SystemExit(0)`` ends the
    block as a normal end, and any other code becomes an error of that example, which fails the
    build (``abort_on_example_error``).
    """
    from sphinx_gallery import gen_rst

    run = gen_rst._exec_and_get_memory
    if getattr(run, "dea_guarded", False):
        return

    def guarded(*args, **kwargs):
        try:
            return run(*args, **kwargs)
        except SystemExit as stop:
            if stop.code in (0, None):
                return False, 0.0
            raise RuntimeError(f"the example exited with code {stop.code}") from stop

    guarded.dea_guarded = True  # type: ignore[attr-defined]
    gen_rst._exec_and_get_memory = guarded


def configuration(root: Path, docs: Path) -> dict:
    """``sphinx_gallery_conf`` for ``docs/conf.py``."""
    _guard_exit()
    output = docs / OUTPUT
    if output.exists():
        shutil.rmtree(output)
    return {
        "examples_dirs": [str(root / "examples"), str(docs / "_tutorials")],
        "gallery_dirs": [str(docs / "gallery"), str(docs / "tutorial")],
        "filename_pattern": r".*\.py$",
        "ignore_pattern": r"(make_gallery|make_examples|__init__)\.py$",
        "reset_argv": ExampleArguments(output),
        "image_scrapers": ("matplotlib", PngScraper(output)),
        "abort_on_example_error": True,
        "only_warn_on_example_error": False,
        "download_all_examples": False,
        "show_signature": False,
        "show_memory": False,
        "remove_config_comments": True,
        "capture_repr": (),
        "min_reported_time": 0,
        "line_numbers": False,
        "plot_gallery": "True",
        "copyfile_regex": "",
        "backreferences_dir": None,
        "matplotlib_animations": False,
        "image_srcset": [],
        # its summary pages load jQuery and DataTables from a CDN; each example's page gives its time
        "write_computation_times": False,
    }


def _is_example(script: str) -> bool:
    return Path(script).parent.name == "examples"


class ExampleArguments:
    """The command line each script runs with: the examples at ``--coarse`` into their own
    folder under the build; the tutorial with none. A class, so the configuration pickles."""

    def __init__(self, output: Path):
        self.output = Path(output)

    def __repr__(self) -> str:  # sphinx-gallery compares configurations by their repr
        return f"ExampleArguments({self.output.name!r})"

    def __call__(self, gallery_conf, script_vars) -> list[str]:
        script = script_vars["src_file"]
        # sphinx-gallery leaves ``__file__`` undefined on purpose; these scripts find their data
        # and helpers through it, as they do when run by hand (its globals exist by now)
        script_vars["example_globals"]["__file__"] = str(script)
        if not _is_example(script):
            return []
        coarse = ["--coarse"] if '"--coarse"' in Path(script).read_text(encoding="utf-8") else []
        return [*coarse, "--out", str(self.output / Path(script).stem)]


class PngScraper:
    """The PNG files an example wrote into its output folder, put on its page in name order."""

    def __init__(self, output: Path):
        self.output = Path(output)

    def __repr__(self) -> str:
        return f"PngScraper({self.output.name!r})"

    def __call__(self, block, block_vars, gallery_conf) -> str:
        from sphinx_gallery.scrapers import figure_rst

        script = block_vars["src_file"]
        if not _is_example(script):
            return ""
        folder = self.output / Path(script).stem
        pictures = sorted(folder.rglob("*.png")) if folder.exists() else []
        seen = block_vars.setdefault("dea_pictures_seen", set())
        names = []
        for picture, target in zip([p for p in pictures if p not in seen], block_vars["image_path_iterator"]):
            shutil.copyfile(picture, target)
            seen.add(picture)
            names.append(target)
        return figure_rst(names, gallery_conf["src_dir"])
