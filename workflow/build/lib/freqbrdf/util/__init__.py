"""Shared utilities: file I/O, logging, argument checks, colour, threads, Mitsuba set-up."""
