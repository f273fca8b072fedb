"""Registration runs on hardware or the virtual lab: poses, observation collection, the log.
"""
