"""`python -m calib_dsl ...`: the `calibc` command, for environments without its script."""

from calib_dsl.cli import main

if __name__ == "__main__":
    main(prog_name="calibc")
