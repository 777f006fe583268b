"""What a run leaves: report.json and the timeseries, plots, the video, the page, exported files and CSV cells.

Imports the stages before it (up to physics and analysis), never the commands.
"""
