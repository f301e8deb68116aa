"""Pixel perception: a small CNN that reads RGB-D only (no instance buffer, no labels).

``net`` holds the network, its vocabulary, the weights' file format and ``predict`` (torch and
numpy only); ``houses`` names the synthetic houses reserved for it (seeds 3000-3999) and how
training houses differ from the generator's; ``frames`` poses and labels one house's frames;
``dataset`` renders them into shards; ``train`` fits the network on them (its crops and loss in
``batches``, its validation figures in ``validation``). The committed weights live in ``weights/``.
"""
