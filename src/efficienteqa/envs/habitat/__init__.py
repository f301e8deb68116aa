"""Habitat-Sim + HM3D (the paper's simulator), imported lazily: see ``env``."""
