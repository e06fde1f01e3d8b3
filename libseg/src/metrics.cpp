// placeholder: replaced by the metrics work
