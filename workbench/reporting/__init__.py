"""Figures and HTML reports; everything is written into a report folder (default reports/)."""
