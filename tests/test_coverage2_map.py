"""The coverage map names what binds at each side in full (a long requirement and its margin are squeezed into the
cell, never cut), and a short text keeps its natural width."""

from __future__ import annotations

import re

from arcube.report.coverage import coverage_map_svg


def _side(patient: str, side: str, met: bool, binding: str | None, margin: float | None, unit: str | None) -> dict:
    return {
        "patient": patient,
        "side": side,
        "label": f"{patient}_{side}",
        "meets_requirements": met,
        "binding": binding,
        "binding_margin": margin,
        "binding_unit": unit,
    }


def test_the_map_cell_says_the_whole_binding_requirement() -> None:
    svg = coverage_map_svg(
        [
            _side("seed17", "R", False, "single_assembly_mode", -120.0, "failing points"),
            _side("seed17", "L", True, "self_clearance", 0.0238, "mm"),
        ]
    )
    found = re.findall(
        r"<text x='[^']*' y='[^']*'( textLength='\d+' lengthAdjust='spacingAndGlyphs')?>([^<]*)</text>", svg
    )
    texts = {text: fit for fit, text in found}
    long = "not served: single_assembly_mode -120 failing points"
    assert long in texts and texts[long]  # in full, squeezed into its cell
    assert texts["served: self_clearance +0.0238 mm"] == ""  # fits: its own width
