// placeholder: replaced by the xdmf work
