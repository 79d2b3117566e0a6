"""The command line (`crashlab COMMAND`): the top layer, which may import every other (docs/architecture.md)."""
from .main import build_parser, main

__all__ = ["build_parser", "main"]
