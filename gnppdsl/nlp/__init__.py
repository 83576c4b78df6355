"""gnppdsl.nlp"""
