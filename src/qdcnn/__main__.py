"""``python -m qdcnn``: the command line."""

from qdcnn.cli import main

main()
