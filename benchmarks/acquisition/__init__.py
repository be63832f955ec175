"""Benchmarks of recording: session file formats, the recorder, the live view, the emulators."""
