// placeholder: replaced by the nifti work
