"""``python -m efficienteqa.models.local keep MODEL IDLE_S``: the keeper process beside a
local model server (``server.keep_main``, ``keeper``)."""

import sys

from efficienteqa.models.local.server import keep_main

if __name__ == "__main__":
    if sys.argv[1:2] != ["keep"] or len(sys.argv) != 4:
        sys.exit("usage: python -m efficienteqa.models.local keep MODEL IDLE_S")
    sys.exit(keep_main(sys.argv[2:]))
