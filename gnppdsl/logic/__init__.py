"""gnppdsl.logic"""
