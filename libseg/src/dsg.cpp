// placeholder: replaced by the dsg work
