"""Environment and open-loop excitation signals."""
