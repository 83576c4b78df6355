"""gnppdsl.reach"""
