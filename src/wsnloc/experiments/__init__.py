"""Experiment families (one module per paper): run estimators on processed tables, score them."""
