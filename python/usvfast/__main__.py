"""`python -m usvfast` runs the command line."""

from usvfast.cli import main

main()
