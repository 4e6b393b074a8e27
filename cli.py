"""Run voxrender from a checkout: ``python cli.py render ...``."""
from voxrender.cli import main

main()
