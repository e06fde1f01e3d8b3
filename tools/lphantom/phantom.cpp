// placeholder: replaced by the phantom work
