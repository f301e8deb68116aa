"""Explore: where to go next (DESIGN 3.2-3.3). Explorers read a MapState and return a Decision."""
