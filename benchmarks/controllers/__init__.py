"""Benchmarks of the example controllers: where backing up holds (reversing)."""
