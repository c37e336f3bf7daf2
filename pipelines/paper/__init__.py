"""``ropeload paper``: the paper's published numbers beside ropeload's, by command.

Each section prints a table (quantity, unit, the paper's number, ropeload's, the
difference) with notes on where each number comes from and what is calibrated rather
than predicted, and writes its figure (PNG) and rows (CSV) to the output folder:

=============  ============================================================  ==========
section        what                                                           module
=============  ============================================================  ==========
``table1``     Table 1 OLS lines vs eq 17: se, z, verdicts (section 4.2.2)   tables
``table2``     Table 2 field test: expected loads, errors, gains, imbalance  tables
``eq9-10``     section 2.2: omega_n, xi by eq 9/10 and by simulation         dynamics
``section3.1`` section 3.1: rig pressure loss, overshoot (simulation)        dynamics
=============  ============================================================  ==========

The paper's tables and text numbers are in :mod:`pipelines.paper.data`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

from pipelines.paper.report import PaperSection, format_section

__all__ = ["SECTIONS", "PaperSection", "format_section", "run_paper"]


def _table1(out: Path) -> PaperSection:
    from pipelines.paper.tables import table1_section

    return table1_section(out)


def _table2(out: Path) -> PaperSection:
    from pipelines.paper.tables import table2_section

    return table2_section(out)


def _eq9_10(out: Path) -> PaperSection:
    from pipelines.paper.dynamics import eq9_10_section

    return eq9_10_section(out)


def _section_3_1(out: Path) -> PaperSection:
    from pipelines.paper.dynamics import section_3_1_section

    return section_3_1_section(out)


#: Subcommand -> section builder (output folder -> section), in the paper's order of
#: ``all``.
SECTIONS: dict[str, Callable[[Path], PaperSection]] = {
    "table1": _table1,
    "table2": _table2,
    "eq9-10": _eq9_10,
    "section3.1": _section_3_1,
}


def run_paper(
    sections: Sequence[str], out_dir: Path, *, emit: Callable[[str], object] | None = None
) -> list[PaperSection]:
    """Build the named sections (``"all"`` for every one) into ``out_dir`` (created).

    ``emit`` receives each section's printed form as soon as it is done (the CLI writes
    it to stdout, so a long section does not hold back the others' output).
    """
    names = list(SECTIONS) if "all" in sections else list(dict.fromkeys(sections))
    unknown = [n for n in names if n not in SECTIONS]
    if unknown:
        raise ValueError(f"unknown paper section(s) {unknown}; one of {[*SECTIONS, 'all']}")
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"output folder {out_dir} is a file, not a folder")
    out_dir.mkdir(parents=True, exist_ok=True)
    done = []
    for name in names:
        section = SECTIONS[name](out_dir)
        done.append(section)
        if emit is not None:
            emit(format_section(section))
    return done
