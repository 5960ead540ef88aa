"""Trajectories: one initial state run in the reference and in each engine, judged by state error,
constraint drift and energy, each with its tolerance and the horizon it holds on."""
