"""Audio in and out: live devices (sounddevice/PortAudio), files (soundfile), analysis
(segmentation, cepstra, transcription to notes) and synthesis (scanned strings, sample playback).

Live devices are optional: every path has an offline twin that needs no hardware.
"""
