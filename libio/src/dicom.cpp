// placeholder: replaced by the dicom work
