studio synth tests/data/configs/small3x100.json -o OUT && cp OUT/small3x100.rrd recordings/  # fingerprint: STUDIO_BLESS=1 pytest tests/studio/test_committed_recordings.py
