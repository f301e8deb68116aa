"""Pixel perception: a small CNN that reads RGB-D only (no instance buffer, no labels).

``net`` holds the network, its vocabulary, the weights' file format and ``predict`` (torch and
numpy only); ``dataset`` renders training frames from synthetic houses reserved for it (seeds
3000-3999); ``train`` fits the network on them. The committed weights live in ``weights/``.
"""
