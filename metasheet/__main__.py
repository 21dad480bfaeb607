"""``python -m metasheet``: the ``metasheet`` command."""

from .cli import main

if __name__ == "__main__":
    main()
