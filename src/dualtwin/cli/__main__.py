"""``python -m dualtwin.cli``."""

from dualtwin.cli import main

main()
