"""gnppdsl.compile"""
