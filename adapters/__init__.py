"""Adapters: one module per port implementation (CSV files, zenoh, MCAP, rerun)."""
