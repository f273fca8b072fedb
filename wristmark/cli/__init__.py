"""The ``wristmark`` command line: ``main`` dispatches to one module per subcommand
(``add_arguments`` + ``run``). It is the top layer: it may import every other package."""
