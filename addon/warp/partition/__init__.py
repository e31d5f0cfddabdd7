"""Partitioning the view for cascades (Scherzer §3; GMNPR §1): splits, adaptive placement, stability, budget."""
