"""gnppdsl.conflicts"""
