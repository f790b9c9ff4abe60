"""Scoring runs, the A/B table, model fits on the design, figures and the report."""
