"""One module per ``bridge-shadow`` subcommand: argument parsing and printing only."""
