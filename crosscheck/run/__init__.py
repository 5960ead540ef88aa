"""`crosscheck run` underneath: each model's checks (checks), spread over worker processes (jobs)
in the order that finishes soonest (order)."""
