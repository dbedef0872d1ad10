"""Flexible bodies in the acceleration-based TMM."""
