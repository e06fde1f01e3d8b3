// placeholder: replaced by the level_set work
