"""Evaluation: datasets run by methods, judged, summarised."""
