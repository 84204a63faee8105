"""``python -m marinebench``: the ``marinebench`` command, for an environment whose scripts folder is not on PATH."""

from marinebench.cli import main

if __name__ == "__main__":
    main()
