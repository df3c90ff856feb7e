"""``python -m robustrtk``: the ``robustrtk`` command (signals handled from the first line)."""

from robustrtk.cli.entry import main

if __name__ == "__main__":  # pragma: no cover
    main()
