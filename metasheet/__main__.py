"""``python -m metasheet`` and the ``metasheet`` console script: the command, with ``run``
watched from a parent process (:mod:`.supervise`)."""

import sys


def main() -> None:
    """Console-script entry point: ``run`` in a supervised child, every other command here."""
    from . import supervise

    args = sys.argv[1:]
    if supervise.wanted(args):
        sys.exit(supervise.supervise(args))
    supervise.become_child()
    from .cli import main as cli_main

    cli_main(args)


if __name__ == "__main__":
    main()
