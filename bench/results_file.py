"""Writing a bench's results page: the generated part is replaced, the hand-written analysis after the marker
`<!-- analysis -->` survives a rerun, and the file appears whole or not at all (written beside it, then renamed)."""
import os

MARKER = "<!-- analysis -->"


def write_keeping_analysis(path, generated):
    keep = ""
    if os.path.exists(path):
        old = open(path).read()
        if MARKER in old:
            keep = "\n" + old[old.index(MARKER):]
    with open(path + ".tmp", "w") as f:
        f.write(generated + keep)
    os.replace(path + ".tmp", path)
