"""Rendering: every HTML report and figure pumpsim draws, from result objects only.

One module per page: `identification`, `diagnosis`, `design` (sweep, sensitivity, optimisation,
with `design_figures`), `pumpdown`, and `simulation` (the figures of a simulated run); `html` holds
the page every report shares. This package is the top layer: nothing below it imports it, and it
never calls into an algorithm -- what a page shows is what the result carries.
"""
