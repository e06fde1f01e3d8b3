// placeholder: replaced by the phantom/pictures work
