"""The words for the quadratic form's exact tail say how it is computed (session 37, left37).

Since session 36 ``core.lsq.quadratic_form_sf`` takes an upper tail (``x > 0``, a positive weight) on a contour
through the saddlepoint (``QF_SADDLE_CONTOUR``), Imhof's quadrature only for ``x <= 0`` and as its fallback.
Docstrings and docs that labelled the residual tests' tails "exact (Imhof)" (their ``x`` is the statistic, > 0)
said what the code no longer does. Held here: no such label left in the code or the docs a user reads (the study
log, docs/discovery-studies.md, is history and keeps its words; core.uncertainty's ``model_error_p`` tails are at
``x = 0``, Imhof's still, and say so without this label)."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The labels that name Imhof as the way the exact tail is computed, bare.
BARE = re.compile(r"\(Imhof[),]|exact: Imhof[;)]|Imhof\)")


def test_no_bare_imhof_label_for_the_exact_tail():
    files = [*sorted((ROOT / "core").glob("*.py")), *sorted((ROOT / "scenarios").rglob("*.py")),
             ROOT / "README.md", *sorted(p for p in (ROOT / "docs").glob("*.md") if p.name != "discovery-studies.md")]
    hits = [f"{p.relative_to(ROOT)}:{i}: {ln.strip()}" for p in files
            for i, ln in enumerate(p.read_text(encoding="utf-8").splitlines(), 1) if BARE.search(ln)]
    assert not hits, "\n".join(hits)
