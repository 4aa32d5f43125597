"""Fig. 1 of Volokh, Chao & Armand: the cartilage spring law, Eq. (2) against Eq. (3).
===================================================================================

Plots normalised stress ``sigma / H`` against engineering strain on [-0.4, 0.4] for the two
limit values of the stiffening exponent, beta = 0.05 and 0.6: Ateshian's law, Eq. (2), solid;
its cubic Taylor polynomial, Eq. (3), dashed; the classical linear spring ``sigma = H eps``
dotted. A second panel shows how far each approximation (linear, cubic, and the 5th- and
7th-order polynomials of Remark 2) lies from Eq. (2) in compression, and a table gives that
relative deviation at strains -0.1, -0.2, -0.3 and -0.4.

Run it with::

    python examples/paper_figure1.py --out figures/

(``--coarse`` draws the curves with fewer points; the table does not change). It writes
``figure1.png``, ``figure1_curves.csv`` and ``figure1_deviation.csv`` into ``--out``
(default ``examples/output/paper_figure1/``) and prints the table.

Every curve is normalised by ``H``, so the picture does not depend on ``H`` (MPa).
The relative deviation of a law from Eq. (2) is ``(sigma_law - sigma_Eq2) / sigma_Eq2``:
negative where the law is softer than Eq. (2).
"""

from __future__ import annotations

import argparse
import io
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: the example must run without a display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

import dea_opt  # noqa: E402
from dea_opt.files import write_data  # noqa: E402

NAME = "paper_figure1"
DEFAULT_OUT = Path(__file__).resolve().parent / "output" / NAME
BETAS = (0.05, 0.6)  # the limit values of the paper's range 0.05 <= beta <= 0.6
TABLE_STRAINS = (-0.1, -0.2, -0.3, -0.4)
#: Approximations of Eq. (2) compared in the table: column name -> Taylor order.
APPROXIMATIONS = {"linear": 1, "cubic": 3, "order5": 5, "order7": 7}
STRAIN_RANGE = (-0.4, 0.4)  # the abscissa of the paper's Fig. 1


# --- the laws ---------------------------------------------------------------------------
def approximation_law(H: float, beta: float, order: int) -> dea_opt.Law:
    """The Taylor polynomial of Eq. (2) of ``order``: linear, Eq. (3) or Remark 2.

    Parameters
    ----------
    H : float
        Aggregate modulus in MPa.
    beta : float
        Stiffening exponent of Eq. (2).
    order : int
        1 gives the classical :class:`~dea_opt.LinearLaw`, 3 the cubic of Eq. (3),
        higher orders the :class:`~dea_opt.PolynomialLaw` of Remark 2.
    """
    if order == 1:
        return dea_opt.LinearLaw(H)
    if order == 3:
        return dea_opt.CubicLaw(H, beta)
    return dea_opt.PolynomialLaw(H, beta, order)


# --- the data ---------------------------------------------------------------------------
def figure1_curves(H: float = 0.6, betas=BETAS, n_points: int = 401) -> dict:
    """The curves of Fig. 1 as arrays of ``sigma / H``.

    Parameters
    ----------
    H : float
        Aggregate modulus in MPa (the normalised curves do not depend on it).
    betas : sequence of float
    n_points : int
        Strains sampled on [-0.4, 0.4]; odd counts include strain 0 and +-0.1 steps.

    Returns
    -------
    dict
        ``{"strain": (n,), "linear": (n,), "eq2": {beta: (n,)}, "eq3": {beta: (n,)}}``.
    """
    strain = np.linspace(*STRAIN_RANGE, n_points)
    return {
        "strain": strain,
        "linear": dea_opt.LinearLaw(H).stress(strain) / H,
        "eq2": {b: dea_opt.AteshianLaw(H, b).stress(strain) / H for b in betas},
        "eq3": {b: dea_opt.CubicLaw(H, b).stress(strain) / H for b in betas},
    }


def relative_deviation(law: dea_opt.Law, reference: dea_opt.Law, strain) -> np.ndarray:
    """``(sigma_law - sigma_ref) / sigma_ref`` at ``strain`` (nonzero strains only)."""
    strain = np.asarray(strain, dtype=float)
    return law.stress(strain) / reference.stress(strain) - 1.0


def deviation_table(H: float = 0.6, betas=BETAS, strains=TABLE_STRAINS, approximations=APPROXIMATIONS) -> pd.DataFrame:
    """Relative deviation of the approximations from Eq. (2), one row per (beta, strain).

    Returns
    -------
    pandas.DataFrame
        Columns ``beta``, ``strain``, ``eq2_stress_over_H`` (Eq. 2's ``sigma / H``) and one
        column per approximation (``linear``, ``cubic``, ``order5``, ``order7``) holding the
        signed relative deviation (a fraction, not per cent).
    """
    rows = []
    for beta in betas:
        eq2 = dea_opt.AteshianLaw(H, beta)
        eps = np.asarray(strains, dtype=float)
        columns = {
            name: relative_deviation(approximation_law(H, beta, order), eq2, eps)
            for name, order in approximations.items()
        }
        sigma = eq2.stress(eps) / H
        for k, e in enumerate(eps):
            rows.append(
                {
                    "beta": beta,
                    "strain": float(e),
                    "eq2_stress_over_H": float(sigma[k]),
                    **{name: float(values[k]) for name, values in columns.items()},
                }
            )
    return pd.DataFrame(rows)


def deviation_curves(H: float = 0.6, betas=BETAS, approximations=APPROXIMATIONS, n_points: int = 201) -> dict:
    """Relative deviation from Eq. (2) over compressive strains (0, 0.4], for panel (b).

    Returns
    -------
    dict
        ``{"strain": (n,), beta: {name: (n,)}}``; strains are negative (compression).
    """
    strain = -np.linspace(STRAIN_RANGE[1], 0.0, n_points, endpoint=False)[::-1]
    out = {"strain": strain}
    for beta in betas:
        eq2 = dea_opt.AteshianLaw(H, beta)
        out[beta] = {
            name: relative_deviation(approximation_law(H, beta, order), eq2, strain)
            for name, order in approximations.items()
        }
    return out


# --- files ------------------------------------------------------------------------------
def write_atomic(path, data) -> Path:
    """Write ``data`` (str or bytes) to ``path`` so that no half-written file is ever seen."""
    return write_data(path, data)


def figure_bytes(fig) -> bytes:
    """The figure as PNG bytes (closed afterwards, so loops do not leak figures)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=130, bbox_inches="tight")
    plt.close(fig)
    return buffer.getvalue()


# --- the picture ------------------------------------------------------------------------
_COLOURS = {0.05: "tab:blue", 0.6: "tab:red"}
_APPROX_STYLE = {"linear": "-", "cubic": "--", "order5": "-.", "order7": ":"}


def plot_figure1(curves: dict, deviations: dict):
    """Panel (a): Fig. 1 of the paper; panel (b): deviation of each approximation."""
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.6))
    strain = curves["strain"]
    for beta, sigma in curves["eq2"].items():
        colour = _COLOURS.get(beta)
        ax.plot(strain, sigma, "-", color=colour, lw=2, label=f"Eq. (2), beta = {beta:g}")
        ax.plot(strain, curves["eq3"][beta], "--", color=colour, lw=1.5, label=f"Eq. (3), beta = {beta:g}")
    ax.plot(strain, curves["linear"], ":", color="k", lw=1.5, label="linear, sigma = H eps")
    ax.axhline(0, color="0.8", lw=0.8)
    ax.axvline(0, color="0.8", lw=0.8)
    ax.set_xlim(*STRAIN_RANGE)
    ax.set_xlabel("engineering strain eps = dh / h")
    ax.set_ylabel("sigma / H")
    ax.set_title("(a) Fig. 1: normalised stress versus strain")
    ax.legend(fontsize=8, loc="upper left")

    compression = -deviations["strain"]
    for beta in (k for k in deviations if k != "strain"):
        for name, values in deviations[beta].items():
            bx.plot(
                compression,
                100 * values,
                linestyle=_APPROX_STYLE.get(name, "-"),
                color=_COLOURS.get(beta),
                label=f"{name}, beta = {beta:g}",
            )
    for level in (-10, -5, 5, 10):
        bx.axhline(level, color="0.75", lw=0.8)
    bx.axvline(0.3, color="0.5", lw=0.8, ls="--")
    bx.set_xlim(0, STRAIN_RANGE[1])
    bx.set_ylim(-45, 10)
    bx.set_xlabel("compressive strain -eps")
    bx.set_ylabel("(sigma_law - sigma_Eq2) / sigma_Eq2  [%]")
    bx.set_title("(b) deviation from Eq. (2) in compression")
    bx.legend(fontsize=7, ncol=2, loc="lower left")
    fig.tight_layout()
    return fig


def format_table(table: pd.DataFrame) -> str:
    """The deviation table as Markdown, deviations in per cent."""
    names = [c for c in table.columns if c in APPROXIMATIONS]
    lines = [
        "| beta | strain | Eq. (2) sigma/H | " + " | ".join(f"{n} [%]" for n in names) + " |",
        "|---|---|---|" + "---|" * len(names),
    ]
    for row in table.itertuples(index=False):
        values = " | ".join(f"{100 * getattr(row, n):+.2f}" for n in names)
        lines.append(f"| {row.beta:g} | {row.strain:+.1f} | {row.eq2_stress_over_H:+.4f} | {values} |")
    return "\n".join(lines)


# --- the script -------------------------------------------------------------------------
def run(out=DEFAULT_OUT, coarse: bool = False, H: float = 0.6) -> dict:
    """Compute Fig. 1 and the deviation table and write them into ``out``.

    Returns
    -------
    dict
        ``curves`` (see :func:`figure1_curves`), ``deviations`` (see
        :func:`deviation_curves`), ``table`` (see :func:`deviation_table`) and ``files``
        (name -> path written).
    """
    out = Path(out)
    n_points = 81 if coarse else 401
    curves = figure1_curves(H, n_points=n_points)
    deviations = deviation_curves(H, n_points=40 if coarse else 200)
    table = deviation_table(H)
    curve_frame = pd.DataFrame(
        {
            "strain": curves["strain"],
            "linear": curves["linear"],
            **{f"eq2_beta{b:g}": v for b, v in curves["eq2"].items()},
            **{f"eq3_beta{b:g}": v for b, v in curves["eq3"].items()},
        }
    )
    files = {
        "png": write_atomic(out / "figure1.png", figure_bytes(plot_figure1(curves, deviations))),
        "curves_csv": write_atomic(out / "figure1_curves.csv", curve_frame.to_csv(index=False)),
        "table_csv": write_atomic(out / "figure1_deviation.csv", table.to_csv(index=False)),
    }
    return {"curves": curves, "deviations": deviations, "table": table, "files": files}


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output directory (default {DEFAULT_OUT})")
    parser.add_argument("--coarse", action="store_true", help="fewer points on the curves (the tests use it)")
    parser.add_argument(
        "--H", type=float, default=0.6, help="aggregate modulus in MPa (the normalised figure does not depend on it)"
    )
    return parser.parse_args(argv)


def main(argv=None) -> dict:
    """Command-line entry point; returns what :func:`run` returns."""
    args = parse_args(argv)
    result = run(args.out, coarse=args.coarse, H=args.H)
    print("Relative deviation from Eq. (2), (sigma_law - sigma_Eq2) / sigma_Eq2:")
    print(format_table(result["table"]))
    for path in result["files"].values():
        print(f"wrote {path}")
    return result


if __name__ == "__main__":
    main()
