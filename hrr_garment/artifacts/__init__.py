"""A trained model as files: the bundle directory and the retrieval database inside it.

Below both ``train`` (which writes them) and ``inference`` (which reads them), so neither of
those imports the other.
"""
