"""Remake the gallery's pictures (examples/gallery, shown by the site's gallery and the README): run the examples at their default setting, keep small copies.

Each example runs with its defaults and writes into ``examples/output/<example>/`` as its
docstring says; the picture the gallery shows is then stored in ``examples/gallery/`` as a
256-colour PNG (no dithering: the plots have few colours, so nothing visible is lost), which
keeps every file under 150 KB.

Run it with::

    python examples/gallery/make_gallery.py

(``--skip-run`` to only copy what ``examples/output/`` already holds; ``--only hip_gait`` to
remake one example's pictures). The knee needs ``../shared/data/knee`` beside the repository;
without it the knee picture is left as it is. Takes about two minutes on two cores, most of
it ``linear_validity.py`` and ``solver_study.py``.
"""

from __future__ import annotations

import argparse
import importlib.util
import io
import sys
from pathlib import Path

from PIL import Image

from dea_opt.files import write_atomic

GALLERY = Path(__file__).resolve().parent
EXAMPLES = GALLERY.parent
OUTPUT = EXAMPLES / "output"
MAX_BYTES = 150_000
#: gallery file -> (example, the file it writes into examples/output/<example>/)
PICTURES = {
    "paper_figure1.png": ("paper_figure1", "figure1.png"),
    "linear_validity_sphere.png": ("linear_validity", "validity_sphere.png"),
    "hip_gait_cycle.png": ("hip_gait", "cycle.png"),
    "hip_gait_exposure.png": ("hip_gait", "exposure.png"),
    "knee_pressure.png": ("knee_from_meshes", "knee_pressure_linear.png"),
    "solver_study.png": ("solver_study", "solver_study.png"),
    "calibrate_from_film.png": ("calibrate_from_film", "calibration.png"),
}


def _load(name):
    """Import an example script as a module (examples/ is not a package)."""
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def compact_png(source: Path) -> bytes:
    """``source`` as a 256-colour PNG (median-cut palette, no dithering)."""
    with Image.open(source) as image:
        palette = image.convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    buffer = io.BytesIO()
    palette.save(buffer, format="PNG", optimize=True)
    return buffer.getvalue()


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--skip-run", action="store_true", help="do not run the examples, copy their outputs")
    parser.add_argument("--only", nargs="+", help="examples to remake (default all)")
    args = parser.parse_args(argv)
    examples = list(dict.fromkeys(example for example, _ in PICTURES.values()))
    examples = [e for e in examples if args.only is None or e in args.only]
    if not args.skip_run:
        for example in examples:
            print(f"running examples/{example}.py")
            try:
                _load(example).main(["--out", str(OUTPUT / example)])
            except SystemExit as exc:  # the knee without its data: keep the old picture
                print(f"  {example} stopped (exit {exc.code}); its pictures are left as they are")
    written = {}
    for name, (example, file) in PICTURES.items():
        source = OUTPUT / example / file
        if example not in examples or not source.is_file():
            continue
        data = compact_png(source)
        if len(data) > MAX_BYTES:
            raise SystemExit(f"{name}: {len(data)} bytes even with 256 colours; draw it smaller")
        written[name] = write_atomic(GALLERY / name, lambda tmp, data=data: tmp.write_bytes(data))
        print(f"wrote {written[name]} ({len(data) / 1000:.0f} KB, from {source.relative_to(EXAMPLES.parent)})")
    return written


if __name__ == "__main__":
    main()
