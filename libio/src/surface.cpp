// placeholder: replaced by the surface work
