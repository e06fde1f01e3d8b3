int main() { return 4; } // placeholder: replaced by the phantom work
