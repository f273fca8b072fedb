"""The ``wristmark`` command line: ``main`` dispatches to one module per subcommand
(``add_arguments`` + ``run``). It is the top layer: it may import every
other package but ``wristmark.sweep``, which drives it (a trial is a ``wristmark experiment``
command line).

The names below are imported on first use (``wristmark/_lazy.py``).
"""

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads it as True)

if TYPE_CHECKING:
    from wristmark.cli.main import COMMANDS, build_parser
    from wristmark.cli.main import main as run_cli
else:
    from wristmark._lazy import attach

    __getattr__, __dir__ = attach(__name__, __file__)
