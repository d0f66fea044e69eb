"""GTR-α: the paper's one-parameter implicit family (docs/theory.md §2.1)."""
