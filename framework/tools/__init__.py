"""Tools built on the core alone: top views and plots, animations, comparison tables, the benchmark and the
stress sweep's scene generator. The reconstruction, the comparison studies and the command line use them
(docs/architecture.md)."""
