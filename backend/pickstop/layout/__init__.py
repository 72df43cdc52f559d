"""Designing the cell: where trays could go (guidance) and where they should (suggestions)."""
