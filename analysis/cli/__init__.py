"""The `merge-irl` command line: the entry point and one module per subcommand."""
