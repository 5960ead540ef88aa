"""One module per `crosscheck` command, named as the command: each has `register(subparsers)`
and the function the command runs. crosscheck.cli puts them together."""
