"""SelfCalUncertainty carries only figures something reads (review31d F5)."""

import dataclasses
import re

from core.uncertainty import SelfCalUncertainty


def test_no_unread_monte_carlo_standard_error_field():
    # u_se (the MC std's standard error, u / sqrt(2 (runs - 1))) was computed, stored and read by nothing, its
    # formula unchecked: removed. Every field left is one the docstring documents (and nothing else is documented).
    fields = {f.name for f in dataclasses.fields(SelfCalUncertainty)}
    assert "u_se" not in fields
    doc = SelfCalUncertainty.__doc__
    documented = {n for names in re.findall(r"^    (\w+(?:, \w+)*) : ", doc, flags=re.M) for n in names.split(", ")}
    assert documented == fields, (documented ^ fields)
