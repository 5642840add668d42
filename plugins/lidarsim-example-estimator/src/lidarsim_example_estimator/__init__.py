"""Example lidarsim plugin: a user's own registration function as a pose estimator."""
