"""Environments: one contract (``base``), one adapter per simulator or robot."""
