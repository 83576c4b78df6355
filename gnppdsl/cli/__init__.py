"""gnppdsl.cli"""
