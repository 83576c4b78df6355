"""gnppdsl.lang"""
