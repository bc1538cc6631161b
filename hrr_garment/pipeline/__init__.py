"""The pipeline: whole jobs made of the stages below it (training: :mod:`.train`), run the same from
Python and from the command line, which only parses arguments and prints."""
