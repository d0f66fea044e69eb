"""EM2: the energy-momentum scheme with a discrete gradient (docs/theory.md §3)."""
