"""What every command runs on: worker processes, interrupts, output files written all at once, the
JSON encoding and the provenance every file carries."""
