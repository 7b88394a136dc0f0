"""The package's version (a leaf module: it imports nothing of the package). It lives in one place,
pyproject.toml; the installed metadata carries it."""
from importlib import metadata as _metadata

try:
    __version__ = _metadata.version("fencesweep")
except _metadata.PackageNotFoundError:  # a source tree on sys.path, never installed
    __version__ = "0+unknown"
