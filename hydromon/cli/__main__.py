"""``python -m hydromon.cli``: the ``hydromon`` command."""

from hydromon.cli.main import entry

entry()
