"""Simulation: state, biology (rot, health, defence, moisture), transport, driver."""
