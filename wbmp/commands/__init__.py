"""One module per ``wbmp`` subcommand: ``add_parser(subparsers)`` and ``run(args) -> int``."""
