"""gnppdsl.view: what a person or a controller does with a solved result (above solve, next to
cli): read the result JSON (`load_result`), export joint trajectories as CSV (`export_csv`),
show the plan in a browser 3-D viewer (`gnppdsl.view.html.write_html`)."""
