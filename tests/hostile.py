"""What every hostile-input test asks of a command: exit 2 and one line, no traceback."""


def one_line_error(main, argv: list[str], capsys) -> str:
    """Run the command ``main(argv)``; assert it refused in one line and return that line."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err
