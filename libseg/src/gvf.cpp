// placeholder: replaced by the gvf work
