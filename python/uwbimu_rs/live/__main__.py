"""``python -m uwbimu_rs.live``: the ``uwbimu-live`` node."""

from uwbimu_rs.live._cli import main

if __name__ == "__main__":
    main()
