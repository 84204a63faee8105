"""``python -m marinebench.cli``, as ``python -m marinebench``."""

from marinebench.cli import main

main()
