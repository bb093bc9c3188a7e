"""``python -m polydem_cli``: the command-line interface (the same as the ``polydem`` script)."""

from polydem_cli.cli import main

main()
