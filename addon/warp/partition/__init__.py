"""Partitioning the view for cascaded shadow maps (Scherzer §3; GMNPR §1):
where the splits go (``splits``: the practical scheme, the tightened range,
stable quantisation; ``adaptive``: Lloyd's model minimised) and how the
texels are shared (``budget``). The method itself is ``methods/cascade.py``."""
