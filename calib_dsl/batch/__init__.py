"""`calibc batch`: many solves on Dask. jobs.py reads the job file (or one model over many
data files) into plain `Job`s; run.py runs one job as `calibc solve --json` would; output.py
keeps the JSON-lines results and what a rerun may skip; schedule.py hands the jobs to Dask;
summary.py prints the table at the end."""
