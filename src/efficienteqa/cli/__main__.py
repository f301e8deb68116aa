"""``python -m efficienteqa.cli``: the ``efficienteqa`` command."""

from efficienteqa.cli import main

main()
