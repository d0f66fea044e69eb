"""HO4: the fourth-order implicit scheme (docs/theory.md §2.2)."""
