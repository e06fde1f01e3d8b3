// placeholder: replaced by the edge_map work
