"""``python -m reference_controllers.vectors``: (re)write the shared test vectors."""

from __future__ import annotations

from reference_controllers.vectors import read_vector, replay
from reference_controllers.vectors.generate import write_all


def main() -> int:
    for path in write_all():
        vector = read_vector(path)
        bad = replay(vector)                      # the file as written must replay exactly
        if bad:
            print(f"{path}: {len(bad)} mismatches after writing, first {bad[0]}")
            return 1
        print(f"{path.name}: {len(vector.rows)} steps")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
