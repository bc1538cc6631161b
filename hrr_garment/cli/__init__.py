"""Command-line tools. Each `main(argv)` returns an exit code; errors print one clear line."""
