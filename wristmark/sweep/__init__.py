"""Parameter sweeps: a spec of keys and values, trials run locally or on a Dask cluster, the report.

A trial is a ``wristmark experiment`` command line run in a worker process, so this package stands
above the command line (``wristmark.cli``); ``wristmark sweep`` is its command (``sweep/command.py``).

The names below are imported on first use (``wristmark/_lazy.py``).
"""

TYPE_CHECKING = False  # typing.TYPE_CHECKING without importing typing (mypy reads it as True)

if TYPE_CHECKING:
    from wristmark.sweep.run import run_sweep
    from wristmark.sweep.spec import load_spec
else:
    from wristmark._lazy import attach

    __getattr__, __dir__ = attach(__name__, __file__)
