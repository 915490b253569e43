"""Subcommands of the `autochair` CLI, one module each with `register(subparsers)`."""
