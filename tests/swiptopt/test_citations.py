"""The paper's equation numbers cited in the code are the compiled paper's numbering.

:data:`CITED` maps each model function to the equation its docstring must cite. Where the
paper's LaTeX source sits beside the repository (``../shared/paper/omeke2023.tex``, as in
the development setup), the test also recounts the numbered equations there and checks
that each cited number lands on the equation named here.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from planners import power_split
from rl import agents, core
from swiptopt import acoustics, auv, coverage, harvesting

#: (object whose docstring cites it, equation number, a fragment of that equation's LaTeX)
CITED = [
    (acoustics.snr_db, 1, r"\gamma=\mathrm{SL}-\mathrm{TL}"),
    (acoustics.source_level_db, 2, "SL=170.8"),
    (acoustics.transmission_loss_db, 3, "k \\times 10"),
    (acoustics.thorp_absorption_db_per_km, 4, "0.11{\\frac{f^2}"),
    (acoustics.turbulence_noise_psd_db, 5, "N_{t}(f)=&17"),
    (acoustics.shipping_noise_psd_db, 6, "N_{s}(f)"),
    (acoustics.wind_noise_psd_db, 7, "N_{w}(f)"),
    (acoustics.thermal_noise_psd_db, 8, "N_{th}(f)"),
    (harvesting.induced_voltage_v, 10, "V_{ind}="),
    (harvesting.available_power_w, 11, "P_{\\nu}="),
    (acoustics.capacity_bps, 15, "B \\log_{2} (1 + \\gamma_{auv})"),
    (auv.drag_force_n, 17, "D=\\frac{1}{2}"),
    (auv.propulsion_power_w, 18, "P_{\\mathrm{prop}}=\\frac{1}{2}"),
    (agents.QLearningAgent, 21, "\\max _a Q(S_{t+1}, a)"),
    (core.td_update, 21, "\\max _a Q(S_{t+1}, a)"),
    (coverage.analytic_coverage_probability, 25, "p_k = \\sum_{i=k}^{n}"),
    (power_split, 23, "\\Gamma\\mathcal{T}"),
]


@pytest.mark.parametrize("obj, number, fragment", CITED, ids=[c[0].__name__ for c in CITED])
def test_docstrings_cite_the_compiled_papers_numbers(obj, number, fragment):
    doc = " ".join((obj.__doc__ or "").split())
    assert re.search(rf"\beqs?\. (\d+, )?{number}\b", doc), f"{obj.__name__} should cite eq. {number}: {doc[:200]}"


def _numbered_equations(tex: str) -> list[str]:
    """The bodies of the numbered display equations, in order (align: one per line)."""
    body = "\n".join(line for line in tex.splitlines() if not line.lstrip().startswith("%"))
    out: list[str] = []
    for env, content in re.findall(r"\\begin\{(equation|align|multline)\}(.*?)\\end\{\1\}", body, re.S):
        out.extend(content.split("\\\\") if env == "align" else [content])
    return out


TEX = Path(__file__).resolve().parents[3] / "shared" / "paper" / "omeke2023.tex"


@pytest.mark.skipif(not TEX.exists(), reason="the paper's LaTeX source is not beside the repository")
def test_the_cited_numbers_are_the_papers_equations():
    equations = _numbered_equations(TEX.read_text(encoding="utf-8"))
    assert len(equations) == 25
    for obj, number, fragment in CITED:
        assert fragment in equations[number - 1], (obj.__name__, number)
