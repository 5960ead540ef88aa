"""The comparisons: named tolerances and records, the reference against an engine at consistent
states (instantaneous), over time (trajectory/), engine against engine (agreement), and the
fault injection and sampling they run on."""
