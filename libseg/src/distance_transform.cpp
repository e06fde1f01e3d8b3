// placeholder: replaced by the distance_transform work
