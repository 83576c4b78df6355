"""gnppdsl.solve"""
