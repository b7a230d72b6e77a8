"""``python -m creatures.body.generate DIR``: write the generated bodies into DIR."""

import sys
from pathlib import Path

from creatures.body.generate import generate

if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python -m creatures.body.generate DIRECTORY")
    for path in generate(Path(sys.argv[1])):
        print(path)
