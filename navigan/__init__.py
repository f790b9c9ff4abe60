"""NaviGAN: the force-decomposed, GAN-trained LSTM planner (Tsai & Oh), its data, training and weights."""
