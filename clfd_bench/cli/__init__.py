"""The ``clfd-bench`` command line. Each subcommand lives in its own module with a
``register(subparsers)`` function; :mod:`clfd_bench.cli.main` wires them together."""
