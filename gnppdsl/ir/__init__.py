"""gnppdsl.ir"""
