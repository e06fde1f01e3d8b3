// placeholder: replaced by the hdf5 work
