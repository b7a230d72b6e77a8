"""Join note models' exports into one weights file, a committee (audio/note_model.py, ``NoteModel``).

Members trained apart (another seed, another round) err on different notes; the committee
averages their probabilities. All must hear one grid (one ``hop``). The committee's onset
threshold is its own, chosen afterwards by ``tools/tune_hearing.py``::

    python -m tools.committee audio/models/notes-offline.npz first.npz second.npz
    python -m tools.tune_hearing audio/models/notes-offline.npz
"""

from __future__ import annotations

import argparse
from pathlib import Path

from audio.note_model import join


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("members", type=Path, nargs="+")
    args = parser.parse_args()
    try:
        join(args.out, args.members)
    except ValueError as e:
        raise SystemExit(str(e)) from None
    print(f"{args.out}: a committee of {len(args.members)}")


if __name__ == "__main__":
    main()
