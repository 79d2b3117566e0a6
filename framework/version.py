"""The installed crashlab's version (package metadata), for reports, checkpoints and `crashlab --version`."""
from importlib.metadata import PackageNotFoundError, version


def package_version() -> str:
    try:
        return version("crashlab")
    except PackageNotFoundError:
        return "unknown (not installed)"
