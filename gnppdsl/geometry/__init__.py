"""gnppdsl.geometry"""
