"""Verbalized confidence, the machinery below exploration and answering (paper, "Exploration -
VC"; DESIGN 3.3, 3.5, 3.6).

One reply holds M answers with confidences ``{r_i, c_i}``; ``parse`` reads them (``yes_no`` a
yes/no with its confidence, ``json_reply`` a bounded JSON object), ``grouping`` normalises them
(``c_i' = c_i / sum c``), groups them into semantic classes ``R_k = E(r_i)`` with
``C_k = sum c_i'`` and takes the argmax. ``logprobs`` reads the same quantities from token
probabilities for the white-box baselines; ``prompts`` loads the package's text templates. The
model calls themselves live with their algorithm: ``explore.vlm_scorer`` and ``answer.calls``.

This package imports nothing from ``explore``, ``answer``, ``perception`` or ``mapping``, and
this file imports nothing at all, so that ``import efficienteqa.vc.parse`` stays cheap.
"""
